"""The observation space of a configured MultiON environment, as data.

Kept apart from :mod:`multion.task.env` so that code which only needs the spaces (building a
policy for a checkpoint, ``GET /v1/spec``, the learner bench) does not import the simulator.
Each sensor's space is its class's (:mod:`multion.task.sensors`).
"""

from __future__ import annotations

from gymnasium import spaces

from multion.config.task import EnvConfig
from multion.task.sensors import SENSOR_CLASSES


def build_observation_space(config: EnvConfig) -> spaces.Dict:
    """The spaces of the configured sensors only (an image Box holds two arrays of its size)."""
    return spaces.Dict({name: SENSOR_CLASSES[name].space(config) for name in config.sensors})
