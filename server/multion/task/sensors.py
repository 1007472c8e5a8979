"""One class per sensor: its observation space for a config, what it observes, and the working
memory it holds. Each class carries its light :class:`~multion.config.sensors.SensorSpec`
(name, access, source), so the registry here and the light one cannot disagree.

Sensors read a :class:`SensorInputs` that the env gathers each step, not the simulator: this
module loads neither PyBullet nor the simulator, so the spaces (``GET /v1/spec``, building a
policy) and the memory estimate (the server process) use it too.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

import numpy as np
from gymnasium import spaces

from multion.config.sensors import SensorSource, SensorSpec, sensor_spec
from multion.config.task import EnvConfig
from multion_client.constants import NUM_CATEGORIES

BYTES_PER_MAP_CELL = 64
"""Per cell of the egocentric map crop: its coordinates and indices while it is cut (float64)."""


@dataclass(frozen=True)
class Frame:
    """One rendered view: what the camera sensors read."""

    rgb: np.ndarray
    depth: np.ndarray
    goal_mask: np.ndarray | None
    """Goal category + 1 per pixel; rendered only when ``goal_mask`` is configured."""


class OracleCrops(Protocol):
    """The oracle map cut around the agent's pose (:class:`multion.task.maps.PoseCrops`)."""

    def full(self) -> np.ndarray: ...

    def revealed(self) -> np.ndarray: ...


@dataclass(frozen=True)
class SensorInputs:
    """What the sensors read at one step, gathered by the env."""

    frame: Frame | None
    """The rendered view; None when no camera sensor is configured."""
    goal_category: int
    distance_to_goal: float
    position: np.ndarray
    yaw: float
    start_position: np.ndarray
    start_yaw: float
    oracle: OracleCrops | None
    """None when no oracle map sensor is configured."""
    goal_position: np.ndarray | None = None
    """The current goal's (x, y), world metres; None when no ``goal_pose`` sensor is configured."""
    goal_seen: bool = False
    """Whether the current goal has been in view this episode (``goal_vector``'s first value)."""


class Sensor(ABC):
    """A sensor: its spec, its space for a config and what it observes."""

    spec: ClassVar[SensorSpec]

    @abstractmethod
    def space(self, config: EnvConfig) -> spaces.Space[Any]: ...

    @abstractmethod
    def observe(self, inputs: SensorInputs) -> np.ndarray: ...

    def working_bytes(self, config: EnvConfig) -> int:
        """Memory its source holds beyond the env's base cost (one count per source: the two
        oracle map sensors share one map). The camera's buffers are in the base cost, since
        ``render()`` draws a frame whatever the sensors."""
        return 0


def _frame(inputs: SensorInputs) -> Frame:
    assert inputs.frame is not None, "the env renders when a camera sensor is configured"
    return inputs.frame


def _crops(inputs: SensorInputs) -> OracleCrops:
    assert inputs.oracle is not None, "the env makes the oracle when a map sensor is configured"
    return inputs.oracle


def _image_shape(config: EnvConfig) -> tuple[int, int]:
    return config.camera.height, config.camera.width


class RGB(Sensor):
    spec = sensor_spec("rgb")

    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        return spaces.Box(0, 255, (*_image_shape(config), 3), np.uint8)

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        return _frame(inputs).rgb


class Depth(Sensor):
    spec = sensor_spec("depth")

    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        cam = config.camera
        high = 1.0 if cam.normalize_depth else cam.max_depth
        return spaces.Box(0.0, high, (*_image_shape(config), 1), np.float32)

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        return _frame(inputs).depth


class Goal(Sensor):
    spec = sensor_spec("goal")

    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        return spaces.Discrete(NUM_CATEGORIES)

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        # a numpy scalar, as a Discrete space's sample is
        return np.int64(inputs.goal_category)  # type: ignore[no-any-return]  # a scalar, not an array


class GoalOnehot(Sensor):
    spec = sensor_spec("goal_onehot")

    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        return spaces.Box(0.0, 1.0, (NUM_CATEGORIES,), np.float32)

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        onehot = np.zeros(NUM_CATEGORIES, dtype=np.float32)
        onehot[inputs.goal_category] = 1.0
        return onehot


def start_frame(
    position: np.ndarray, start_position: np.ndarray, start_yaw: float
) -> tuple[float, float]:
    """``position`` (x, y world metres) as the displacement from the episode's start in its
    start frame: metres ahead, metres left (the ``gps`` sensor's reading)."""
    c, s = math.cos(start_yaw), math.sin(start_yaw)
    dx, dy = position - start_position
    return float(c * dx + s * dy), float(-s * dx + c * dy)


class GPS(Sensor):
    spec = sensor_spec("gps")

    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        return spaces.Box(-np.inf, np.inf, (2,), np.float32)

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        ahead_left = start_frame(inputs.position, inputs.start_position, inputs.start_yaw)
        return np.array(ahead_left, dtype=np.float32)


class Compass(Sensor):
    spec = sensor_spec("compass")

    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        return spaces.Box(-np.pi, np.pi, (1,), np.float32)

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        heading = math.remainder(inputs.yaw - inputs.start_yaw, 2 * math.pi)
        return np.array([heading], dtype=np.float32)


class _OracleMapSensor(Sensor):
    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        size = config.maps.ego_size
        return spaces.Box(0, 255, (size, size, 2), np.uint8)

    def working_bytes(self, config: EnvConfig) -> int:
        return config.maps.ego_size**2 * BYTES_PER_MAP_CELL


class OracleMapSensor(_OracleMapSensor):
    spec = sensor_spec("oracle_map")

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        return _crops(inputs).full()


class OracleEgoMapSensor(_OracleMapSensor):
    spec = sensor_spec("oracle_ego_map")

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        return _crops(inputs).revealed()


class GoalMask(Sensor):
    spec = sensor_spec("goal_mask")

    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        return spaces.Box(0, NUM_CATEGORIES, _image_shape(config), np.uint8)

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        mask = _frame(inputs).goal_mask
        assert mask is not None, "the env segments the frame when goal_mask is configured"
        return mask


class GoalDistance(Sensor):
    spec = sensor_spec("goal_distance")

    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        return spaces.Box(0.0, np.inf, (1,), np.float32)

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        # capped: an unreachable goal's infinite distance is not a float32 a client can use
        return np.array([min(inputs.distance_to_goal, 1e6)], dtype=np.float32)


class GoalVector(Sensor):
    """Ground truth for auxiliary heads (Marza et al., IROS 2022): has the current goal been in
    view this episode (within ``GOAL_VECTOR_SEEN_DISTANCE``), its bearing from the agent's
    heading (radians in [-pi, pi), counter-clockwise, so left is positive) and its straight-line
    distance (metres)."""

    spec = sensor_spec("goal_vector")

    def space(self, config: EnvConfig) -> spaces.Space[Any]:
        low = np.array([0.0, -np.pi, 0.0], dtype=np.float32)
        high = np.array([1.0, np.pi, np.inf], dtype=np.float32)
        return spaces.Box(low, high, (3,), np.float32)

    def observe(self, inputs: SensorInputs) -> np.ndarray:
        assert inputs.goal_position is not None, "the env passes the goal for goal_vector"
        dx, dy = inputs.goal_position[:2] - inputs.position[:2]
        bearing = math.remainder(math.atan2(dy, dx) - inputs.yaw, 2 * math.pi)
        bearing = -math.pi if bearing >= math.pi else bearing  # [-pi, pi): float32-safe
        return np.array([float(inputs.goal_seen), bearing, math.hypot(dx, dy)], dtype=np.float32)


SENSOR_CLASSES: dict[str, Sensor] = {
    sensor.spec.name: sensor
    for sensor in (
        RGB(),
        Depth(),
        Goal(),
        GoalOnehot(),
        GPS(),
        Compass(),
        OracleMapSensor(),
        OracleEgoMapSensor(),
        GoalMask(),
        GoalDistance(),
        GoalVector(),
    )
}
"""Every sensor by name, in the light registry's order (a test checks they match)."""

OBSERVATION_ORDER = (
    "rgb",
    "depth",
    "goal_mask",
    "goal",
    "goal_onehot",
    "goal_distance",
    "gps",
    "compass",
    "oracle_map",
    "oracle_ego_map",
    "goal_vector",
)
"""The order of an observation's keys, whatever the config's order: the order they have always
had (clients and recorded runs see it on the wire)."""


def configured_sensors(config: EnvConfig) -> list[Sensor]:
    """The sensors of ``config``, in observation order."""
    return [SENSOR_CLASSES[name] for name in OBSERVATION_ORDER if name in config.sensors]


def uses_source(sensors: Iterable[Sensor], source: SensorSource) -> bool:
    """Does any of ``sensors`` read ``source``?"""
    return any(sensor.spec.source == source for sensor in sensors)


def sensors_working_bytes(config: EnvConfig) -> int:
    """The working memory of the configured sensors' sources, each source counted once."""
    by_source = {s.spec.source: s.working_bytes(config) for s in configured_sensors(config)}
    return sum(by_source.values())
