"""The simulator: a scene, its navigable grid, the agent's pose and its camera.

Motion follows the navigable grid, like Habitat's navmesh: a forward step whose straight sweep
leaves the (radius-eroded) navigable area is refused, the agent stays where it was and the step
counts as a collision (no sliding, SPEC §2).
"""

from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict

import numpy as np

from multion.config.sim import AgentConfig, CameraConfig, NavGridConfig
from multion.scenes.registry import is_mesh_scene, layout_for
from multion.sim import grid_cache
from multion.sim.camera import Camera, CameraImage
from multion.sim.navgrid import NavGrid, build_navgrid
from multion.sim.world import PyBulletWorld
from multion_client.constants import Action

_GRID_CACHE: OrderedDict[tuple[str, NavGridConfig], NavGrid] = OrderedDict()
_GRID_CACHE_SIZE = 32


def load_world(scene_id: str, renderer: str = "tiny") -> PyBulletWorld:
    """Build the PyBullet world of a scene id (``house-00042``, ``room-6x4``, or a mesh path),
    ready for ``renderer`` (``CameraConfig.renderer``)."""
    if is_mesh_scene(scene_id):
        return PyBulletWorld.from_mesh(scene_id, renderer)
    return PyBulletWorld.from_layout(layout_for(scene_id), renderer)


def navgrid_for(scene_id: str, world: PyBulletWorld, config: NavGridConfig) -> NavGrid:
    """The navigable grid of a scene: from this process's memory, else from the disk cache
    (:mod:`multion.sim.grid_cache`), else computed by ray casts and saved there."""
    key = (scene_id, config)
    if key in _GRID_CACHE:
        _GRID_CACHE.move_to_end(key)
        return _GRID_CACHE[key]
    grid, path, disk_key = grid_cache.cached_grid(scene_id, config)
    if grid is None:
        build = config
        if config.floor_z is None and not is_mesh_scene(scene_id):
            # A procedural scene knows its floor: finding it by ray casts could take a large
            # roof for the floor (issue 33). Where the search was right the grid is the same,
            # so the cache key stays that of the searched floor.
            build = dataclasses.replace(config, floor_z=layout_for(scene_id).floor_z)
        grid = build_navgrid(world, build)
        grid_cache.store(path, grid, disk_key)
    _GRID_CACHE[key] = grid
    while len(_GRID_CACHE) > _GRID_CACHE_SIZE:
        _GRID_CACHE.popitem(last=False)
    return grid


class Simulator:
    """Holds one scene at a time and the agent in it."""

    def __init__(
        self,
        agent: AgentConfig = AgentConfig(),
        camera: CameraConfig = CameraConfig(),
        navgrid: NavGridConfig = NavGridConfig(),
    ) -> None:
        self.agent_config = agent
        self.camera_config = camera
        self.navgrid_config = NavGridConfig(
            **{
                **navgrid.__dict__,
                "agent_radius": agent.radius,
                "agent_height": agent.height,
                "view_height": camera.sensor_height,
            }
        )
        self.scene_id: str | None = None
        self.world: PyBulletWorld | None = None
        self.grid: NavGrid | None = None
        self.camera: Camera | None = None
        self.position = np.zeros(2)
        self.yaw = 0.0
        self._start_yaw = 0.0
        self._turns = 0

    def load_scene(self, scene_id: str) -> NavGrid:
        """Switch to ``scene_id`` (a no-op when it is already loaded); returns its grid."""
        if scene_id != self.scene_id or self.world is None:
            self.close()
            self.world = load_world(scene_id, self.camera_config.renderer)
            self.grid = navgrid_for(scene_id, self.world, self.navgrid_config)
            self.camera = Camera(
                self.camera_config,
                self.world.client,
                self.world.renderer,
                self.world.lighting,
                gl=self.world.gl,
            )
            self.scene_id = scene_id
        assert self.grid is not None
        return self.grid

    @property
    def renderer(self) -> str | None:
        """The renderer in use ("tiny", "gl" or "egl"), None before a scene is loaded."""
        return self.world.renderer if self.world is not None else None

    def close(self) -> None:
        if self.world is not None:
            self.world.close()
        self.world = None
        self.camera = None
        self.scene_id = None

    # ------------------------------------------------------------------ agent
    def set_agent(self, position: np.ndarray, yaw: float) -> None:
        self.position = np.asarray(position, dtype=np.float64)[:2].copy()
        self._start_yaw = float(yaw)
        self._turns = 0
        self.yaw = _wrap(self._start_yaw)

    def act(self, action: int) -> bool:
        """Apply a motion action; returns True when a forward step was blocked (a collision).

        Headings are kept as start yaw plus a whole number of turns, so they never drift.
        """
        if action == Action.TURN_LEFT:
            self._turns += 1
        elif action == Action.TURN_RIGHT:
            self._turns -= 1
        elif action == Action.MOVE_FORWARD:
            step = self.agent_config.forward_step
            target = self.position + step * np.array([math.cos(self.yaw), math.sin(self.yaw)])
            assert self.grid is not None
            if not self.grid.segment_is_navigable(self.position, target):
                return True
            self.position = target
        self.yaw = _wrap(
            self._start_yaw + math.radians(self.agent_config.turn_angle_deg) * self._turns
        )
        return False

    def render(self, segmentation: bool = False) -> CameraImage:
        assert self.camera is not None and self.grid is not None, "load a scene first"
        return self.camera.render(
            float(self.position[0]),
            float(self.position[1]),
            self.yaw,
            self.grid.floor_z,
            segmentation,
        )


def _wrap(angle: float) -> float:
    """Angle in (-pi, pi]."""
    wrapped = math.remainder(angle, 2 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped
