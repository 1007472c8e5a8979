"""Configs of the simulator: the agent's body, its camera and the navigable grid."""

from __future__ import annotations

import math
from dataclasses import dataclass

from multion.config.ranges import Range, bounded, check_fields, one_of, require

RENDERERS = ("tiny", "gl", "egl", "auto")
EGL_PACKAGES = "libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri"
"""Debian packages of Mesa's EGL, which OpenGL needs on a machine without a GPU (named in the
simulator's errors and in the leaderboard's, which never imports the simulator)."""


@dataclass(frozen=True)
class CameraConfig:
    """The RGB-D sensor (SPEC §2; the reference code's values)."""

    width: int = bounded(256, 1, 1024)
    """Image width in pixels (1024 bounds an image's memory, about 100 bytes a pixel)."""
    height: int = bounded(256, 1, 1024)
    hfov_deg: float = bounded(79.0, 1.0, 170.0)
    """Horizontal field of view, degrees."""
    sensor_height: float = bounded(0.88, 0.05, 3.0)
    """Camera height above the floor, metres."""
    min_depth: float = bounded(0.0, 0.0, 100.0)
    max_depth: float = bounded(10.0, 0.0, 100.0, low_open=True)
    normalize_depth: bool = True
    """Depth in metres clipped to ``[min_depth, max_depth]``, then mapped to ``[0, 1]``.
    [0, 10] m, normalised, is habitat's default, which the reference code keeps
    (saimwani/multiON ``habitat/config/default.py`` lines 303-305: ``MIN_DEPTH 0.0``,
    ``MAX_DEPTH 10.0``, ``NORMALIZE_DEPTH True``; ``configs/tasks/multinav_mp3d.yaml`` does not
    change them, and ``habitat_baselines/rl/ppo/policy.py`` line 318 multiplies depth by 10 to get
    metres back). The default was [0.5, 5] m until issue 31."""
    near: float = bounded(0.02, 0.001, 1.0)
    """Near clipping plane, metres."""
    far: float = bounded(60.0, 1.0, 1000.0)
    """Far clipping plane, metres."""
    renderer: str = one_of("tiny", RENDERERS)
    """Renderer, one of ``tiny`` (PyBullet's CPU TinyRenderer, identical pixels everywhere:
    the reference), ``gl`` (the project's OpenGL renderer of the same world: a GPU, or Mesa's
    llvmpipe on a CPU; an error naming what to install where no context opens), ``egl``
    (PyBullet's EGL plugin) or ``auto`` (gl when its context opens, else tiny)."""

    def __post_init__(self) -> None:
        check_fields(self, "camera")
        require(
            self.min_depth < self.max_depth,
            f"camera.min_depth ({self.min_depth}) must be below camera.max_depth "
            f"({self.max_depth})",
        )
        require(
            self.near < self.far, f"camera.near ({self.near}) must be below camera.far ({self.far})"
        )

    @property
    def vfov_deg(self) -> float:
        half = math.radians(self.hfov_deg) / 2
        return math.degrees(2 * math.atan(math.tan(half) * self.height / self.width))


@dataclass(frozen=True)
class AgentConfig:
    """The agent's body and its action magnitudes (paper §3)."""

    radius: float = bounded(0.1, 0.02, 1.0)
    """Metres; free space is eroded by it."""
    height: float = bounded(1.5, 0.2, 3.0)
    forward_step: float = bounded(0.25, 0.01, 2.0)
    """Metres per MOVE_FORWARD."""
    turn_angle_deg: float = bounded(30.0, 0.1, 180.0)
    """Degrees per TURN_LEFT / TURN_RIGHT."""

    def __post_init__(self) -> None:
        check_fields(self, "agent")


MAX_OBSTACLE_SWEEPS = 8


@dataclass(frozen=True)
class NavGridConfig:
    """How the navigable grid is computed."""

    cell_size: float = bounded(0.05, 0.02, 0.25)
    """Side of a grid cell in metres (cells, ray casts and memory grow as its inverse square)."""
    agent_radius: float = bounded(0.1, 0.02, 1.0)
    """Free space is eroded by this radius (the simulator sets it from ``agent.radius``)."""
    agent_height: float = bounded(1.5, 0.2, 3.0)
    """Geometry below this height above the floor blocks the agent (from ``agent.height``)."""
    max_step_height: float = bounded(0.05, 0.0, 0.5)
    """A surface this close to the floor height still counts as floor."""
    obstacle_heights: tuple[float, ...] = (0.3, 1.45)
    """Heights above the floor of the horizontal ray sweeps that catch walls and tall furniture:
    1 to 8 heights, each in [0, 3] metres."""
    view_height: float = bounded(0.88, 0.05, 3.0)
    """Height of the sweep whose hits block the line of sight (from ``camera.sensor_height``)."""
    floor_z: float | None = None
    """Floor height in [-1000, 1000] metres; ``None`` finds it from the geometry."""
    margin: float = bounded(0.25, 0.0, 5.0)
    """Extra border around the scene bounds, in metres."""

    def __post_init__(self) -> None:
        check_fields(self, "navgrid")
        heights = Range(0.0, 3.0)
        require(
            1 <= len(self.obstacle_heights) <= MAX_OBSTACLE_SWEEPS
            and all(heights.allows(h) for h in self.obstacle_heights),
            f"navgrid.obstacle_heights = {self.obstacle_heights!r:.80} is out of range: allowed "
            f"1 to {MAX_OBSTACLE_SWEEPS} heights, each in {heights.describe()}",
        )
        require(
            self.floor_z is None or Range(-1000.0, 1000.0).allows(self.floor_z),
            f"navgrid.floor_z = {self.floor_z!r:.80} is out of range: allowed null or "
            "[-1000, 1000]",
        )
