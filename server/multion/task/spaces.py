"""The observation space of a configured MultiON environment, as data.

Kept apart from :mod:`multion.task.env` so that code which only needs the spaces (building a
policy for a checkpoint, ``GET /v1/spec``, the learner bench) does not import the simulator.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium import spaces

from multion.config.task import EnvConfig
from multion_client.constants import NUM_CATEGORIES


def build_observation_space(config: EnvConfig) -> spaces.Dict:
    """The spaces of the configured sensors only (an image Box holds two arrays of its size)."""
    cam, size = config.camera, config.maps.ego_size
    image = (cam.height, cam.width)
    builders: dict[str, Callable[[], spaces.Space[Any]]] = {
        "rgb": lambda: spaces.Box(0, 255, (*image, 3), np.uint8),
        "depth": lambda: spaces.Box(
            0.0, 1.0 if cam.normalize_depth else cam.max_depth, (*image, 1), np.float32
        ),
        "goal": lambda: spaces.Discrete(NUM_CATEGORIES),
        "goal_onehot": lambda: spaces.Box(0.0, 1.0, (NUM_CATEGORIES,), np.float32),
        "gps": lambda: spaces.Box(-np.inf, np.inf, (2,), np.float32),
        "compass": lambda: spaces.Box(-np.pi, np.pi, (1,), np.float32),
        "oracle_map": lambda: spaces.Box(0, 255, (size, size, 2), np.uint8),
        "oracle_ego_map": lambda: spaces.Box(0, 255, (size, size, 2), np.uint8),
        "goal_mask": lambda: spaces.Box(0, NUM_CATEGORIES, image, np.uint8),
        "goal_distance": lambda: spaces.Box(0.0, np.inf, (1,), np.float32),
    }
    return spaces.Dict({name: builders[name]() for name in config.sensors})
