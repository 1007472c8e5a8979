"""What each sensor is, as data: its name, who may receive it, and what it reads.

This is the light half of a sensor (no simulator, no gymnasium): the config checks sensor names
against it, the challenge decides which tracks may receive a sensor from its ``access``, and the
spec lists it. The observing half (space, ``observe``, working memory) is
:mod:`multion.task.sensors`, one class per sensor, each holding its :class:`SensorSpec` from
:data:`SENSOR_SPECS`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

SensorAccess = Literal["standard", "oracle", "training"]
"""Who may receive a sensor in a challenge: every track (``standard``), oracle tracks only
(``oracle``: privileged knowledge of the map or the geodesic distance), or no track
(``training``: ground-truth labels for supervising a recogniser)."""
SensorSource = Literal["camera", "goal", "pose", "geodesic", "oracle_map", "goal_pose"]
"""What a sensor reads: the rendered frame, the current goal, the agent's pose relative to its
start, the geodesic distance field, the oracle map of the scene, or where the current goal is
from the agent (and whether it has been in view)."""

GOAL_VECTOR_SEEN_DISTANCE = 6.0
"""``goal_vector``'s "seen" flag: the goal has been within this many metres, in the camera's
field of view with a clear line of sight. 6 m is the fog-of-war map's visibility distance from
which Marza et al. (IROS 2022) label their "seen" auxiliary task
(PierreMarza/teaching_agents_how_to_map ``habitat/config/default.py`` l. 169); the oracle ego
map reveals 5 m (``maps.view_distance``, the supplement's)."""


@dataclass(frozen=True)
class SensorSpec:
    """One sensor, as data."""

    name: str
    access: SensorAccess
    source: SensorSource
    summary: str

    @property
    def privileged(self) -> bool:
        """Knowledge a real agent does not have: never on a standard track."""
        return self.access != "standard"


SENSOR_SPECS: tuple[SensorSpec, ...] = (
    SensorSpec("rgb", "standard", "camera", "(H, W, 3) uint8 colour image"),
    SensorSpec("depth", "standard", "camera", "(H, W, 1) float32 planar depth"),
    SensorSpec("goal", "standard", "goal", "the current goal's category, 0..7"),
    SensorSpec("goal_onehot", "standard", "goal", "(8,) float32 one-hot current goal"),
    SensorSpec("gps", "standard", "pose", "(2,) position in the start frame, metres"),
    SensorSpec("compass", "standard", "pose", "(1,) heading relative to the start, radians"),
    SensorSpec("oracle_map", "oracle", "oracle_map", "(S, S, 2) egocentric crop of the map"),
    SensorSpec("oracle_ego_map", "oracle", "oracle_map", "(S, S, 2) the crop, where seen so far"),
    SensorSpec("goal_mask", "training", "camera", "(H, W) uint8 goal category + 1 per pixel"),
    SensorSpec("goal_distance", "oracle", "geodesic", "(1,) geodesic metres to the goal"),
    SensorSpec(
        "goal_vector",
        "training",
        "goal_pose",
        "(3,) float32: current goal seen yet (0/1), its bearing (rad, left +), metres to it",
    ),
)
"""Every sensor, registered once; their order is the order the spec and messages list them."""

SENSORS: tuple[str, ...] = tuple(spec.name for spec in SENSOR_SPECS)
"""The names of every sensor (``EnvConfig.sensors`` takes any of them)."""


def sensor_spec(name: str) -> SensorSpec:
    """The spec of sensor ``name``; a KeyError naming the known sensors otherwise."""
    for spec in SENSOR_SPECS:
        if spec.name == name:
            return spec
    raise KeyError(f"unknown sensor {name!r}; known sensors: {list(SENSORS)}")


def sensors_with_access(access: tuple[SensorAccess, ...]) -> tuple[str, ...]:
    """The names of the sensors whose access is one of ``access``, in registry order."""
    return tuple(spec.name for spec in SENSOR_SPECS if spec.access in access)
