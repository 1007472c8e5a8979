"""Task constants shared by the server and every client: action ids and goal categories."""

from __future__ import annotations

from enum import IntEnum


class Action(IntEnum):
    """The four actions of MultiON, in the reference code's order."""

    FOUND = 0
    MOVE_FORWARD = 1
    TURN_LEFT = 2
    TURN_RIGHT = 3


NUM_ACTIONS = len(Action)

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

# Oracle-map cell values (channel 0: occupancy, channel 1: goal category + 1, 0 for none).
MAP_UNKNOWN = 0  # outside the scene, or not yet discovered (ego map)
MAP_FREE = 1
MAP_OCCUPIED = 2
