"""Task constants shared by the server and every client: action ids and goal categories."""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Action(IntEnum):
    """The four actions of MultiON, in the reference code's order."""

    FOUND = 0
    MOVE_FORWARD = 1
    TURN_LEFT = 2
    TURN_RIGHT = 3


NUM_ACTIONS = len(Action)
ACTIONS_TEXT = ", ".join(f"{a.value} {a.name}" for a in Action)


def action_id(value: object) -> int | None:
    """``value`` as an action id, or None if it is not one.

    Actions are integers in 0..3: Python or numpy integers, or 0-d integer arrays. Floats
    (even ``1.0``), bools and strings are refused, by the in-process env, the server's session
    and run routes, and the light client's ``RunEnv`` alike: each checks with this function.
    """
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        return None
    return int(value) if 0 <= value < NUM_ACTIONS else None


# The k = 8 goal categories (paper §3); a category id is the index in this tuple.
GOAL_CATEGORIES: tuple[str, ...] = (
    "red",
    "green",
    "blue",
    "cyan",
    "magenta",
    "yellow",
    "black",
    "white",
)
GOAL_RGBA: tuple[tuple[float, float, float, float], ...] = (
    (1.0, 0.0, 0.0, 1.0),
    (0.0, 1.0, 0.0, 1.0),
    (0.0, 0.0, 1.0, 1.0),
    (0.0, 1.0, 1.0, 1.0),
    (1.0, 0.0, 1.0, 1.0),
    (1.0, 1.0, 0.0, 1.0),
    (0.0, 0.0, 0.0, 1.0),
    (1.0, 1.0, 1.0, 1.0),
)
NUM_CATEGORIES = len(GOAL_CATEGORIES)
REFERENCE_CATEGORY_NAMES: tuple[str, ...] = (
    "red",
    "green",
    "blue",
    "yellow",
    "white",
    "pink",
    "black",
    "cyan",
)
"""The reference code's goal order and names (saimwani/multiON ``habitat/core/env.py`` l. 252-253,
``cylinder_<name>``): MultiON episode files and habitat agents' ``multiobjectgoal`` use it."""
REFERENCE_TO_CATEGORY: tuple[int, ...] = tuple(
    GOAL_CATEGORIES.index("magenta" if name == "pink" else name)
    for name in REFERENCE_CATEGORY_NAMES
)
"""The category id here of each reference index (the reference's pink is our magenta)."""

# The supplement's shape goals ("Varying target object shapes"): 8 red shapes 0.4 m across on
# thin supports; a category id is the index in this tuple.
SHAPE_CATEGORIES: tuple[str, ...] = (
    "cone",
    "cube",
    "cylinder",
    "frustum",
    "joined_frustums",
    "sphere",
    "tetrahedron",
    "torus",
)
SHAPE_RGBA: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 1.0)
"""Every shape goal is red (supplement)."""

# MultiON 2.0's real-object goals, from the models PyBullet ships (multion.sim.goal_objects).
OBJECT_CATEGORIES: tuple[str, ...] = (
    "teddy_bear",
    "soccer_ball",
    "mug",
    "toy_car",
    "toy_robot",
    "toy_rover",
    "toy_brick",
    "tray",
)

# Unseen objects (the 2023 edition's zero-shot classes): random shapes from pybullet_data's
# random_urdfs, models 0-7 to train with and 500-507, never seen in training, to test on.
UNSEEN_TRAIN_CATEGORIES: tuple[str, ...] = tuple(f"random_{i:03d}" for i in range(8))
UNSEEN_TEST_CATEGORIES: tuple[str, ...] = tuple(f"random_{i:03d}" for i in range(500, 508))

GOAL_SETS: dict[str, tuple[str, ...]] = {
    "colours": GOAL_CATEGORIES,
    "shapes": SHAPE_CATEGORIES,
    "objects": OBJECT_CATEGORIES,
    "unseen_train": UNSEEN_TRAIN_CATEGORIES,
    "unseen_test": UNSEEN_TEST_CATEGORIES,
}
"""``task.goal_set`` → its category names: ``colours``, the paper's 8 cylinders (the default),
``shapes`` (the supplement's), ``objects`` (everyday objects, MultiON 2.0's REAL-OBJECTS
track), or ``unseen_train`` / ``unseen_test`` (disjoint random objects: train on one, test on the
other). All have 8 categories, so the same episodes (category ids) serve every set."""
DEFAULT_GOAL_SET = "colours"


def goal_categories(goal_set: str = DEFAULT_GOAL_SET) -> tuple[str, ...]:
    """The category names of ``goal_set``; a ValueError naming the sets otherwise."""
    if goal_set not in GOAL_SETS:
        raise ValueError(f"unknown goal set {goal_set!r}; goal sets: {', '.join(GOAL_SETS)}")
    return GOAL_SETS[goal_set]


# Oracle-map cell values (channel 0: occupancy, channel 1: goal category + 1, 0 for none).
MAP_UNKNOWN = 0  # outside the scene, or not yet discovered (ego map)
MAP_FREE = 1
MAP_OCCUPIED = 2
