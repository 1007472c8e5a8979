"""Oracle maps and visibility (paper §4.2 and supplement).

The global oracle map is a coarse grid (0.8 m cells) with two channels: occupancy
(``MAP_UNKNOWN`` outside the scene, ``MAP_FREE``, ``MAP_OCCUPIED``) and goal category + 1 (0 for
no goal). Agents receive an egocentric crop rotated to their heading: row 0 is ahead, column 0 is
to the left, the agent is in the centre cell. The oracle *ego* map holds only the cells the agent
has seen: within the field of view, within ``view_distance``, and not hidden behind geometry at
the camera's height (the line of sight is traced on the fine grid, so walls occlude).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from multion.ranges import bounded, check_fields, require
from multion.sim.navgrid import NavGrid
from multion.task.episode import Goal
from multion_client.constants import MAP_FREE, MAP_OCCUPIED, MAP_UNKNOWN


@dataclass(frozen=True)
class MapConfig:
    """Oracle map and visibility settings."""

    cell_size: float = bounded(0.8, 0.05, 5.0)
    """Side of an oracle-map cell, metres (paper: 0.8)."""
    ego_size: int = bounded(13, 1, 1001)
    """Side of the egocentric crop, cells (odd, so the agent has a centre cell). 13 cells of
    0.8 m (about 10 m) is the reference configuration's crop: large enough to plan the next few
    rooms, too small to show a whole house, so an agent must remember what it has seen."""
    free_fraction: float = bounded(0.5, 0.0, 1.0)
    """A coarse cell is free when at least this fraction of its fine cells is navigable."""
    view_distance: float = bounded(5.0, 0.1, 50.0)
    """How far the agent sees, metres (supplement: 5 m)."""
    view_rays: int = bounded(80, 1, 1000)
    """Rays traced across the field of view to reveal the ego map."""

    def __post_init__(self) -> None:
        check_fields(self, "maps")
        require(self.ego_size % 2 == 1, f"maps.ego_size must be odd, got {self.ego_size}")


class OracleMap:
    """The global oracle map of one scene, with the current episode's goals."""

    def __init__(self, grid: NavGrid, config: MapConfig) -> None:
        self.grid = grid
        self.config = config
        factor = max(1, round(config.cell_size / grid.cell_size))
        self.factor = factor
        rows = -(-grid.shape[0] // factor)
        cols = -(-grid.shape[1] // factor)
        nav = np.zeros((rows * factor, cols * factor), dtype=np.float32)
        inside = np.zeros_like(nav, dtype=bool)
        nav[: grid.shape[0], : grid.shape[1]] = grid.navigable
        inside[: grid.shape[0], : grid.shape[1]] = grid.inside
        fraction = nav.reshape(rows, factor, cols, factor).mean(axis=(1, 3))
        any_inside = inside.reshape(rows, factor, cols, factor).any(axis=(1, 3))
        occupancy = np.where(any_inside, MAP_OCCUPIED, MAP_UNKNOWN).astype(np.uint8)
        occupancy[fraction >= config.free_fraction] = MAP_FREE
        self.layers = np.zeros((rows, cols, 2), dtype=np.uint8)
        self.layers[..., 0] = occupancy
        self.coarse_size = factor * grid.cell_size
        half = config.ego_size // 2
        r, c = np.meshgrid(np.arange(config.ego_size), np.arange(config.ego_size), indexing="ij")
        self._forward = (half - r).astype(np.float64) * self.coarse_size
        self._left = (half - c).astype(np.float64) * self.coarse_size

    def set_goals(self, goals: Sequence[Goal]) -> None:
        self.layers[..., 1] = 0
        for goal in goals:
            row, col = self.coarse_cell(np.asarray(goal.position[:2]))
            if 0 <= row < self.layers.shape[0] and 0 <= col < self.layers.shape[1]:
                self.layers[row, col, 1] = goal.category + 1

    def coarse_cell(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xy = np.asarray(xy, dtype=np.float64)
        col = np.floor((xy[..., 0] - self.grid.origin[0]) / self.coarse_size).astype(np.int64)
        row = np.floor((xy[..., 1] - self.grid.origin[1]) / self.coarse_size).astype(np.int64)
        return row, col

    def egocentric(self, layers: np.ndarray, position: np.ndarray, yaw: float) -> np.ndarray:
        """Crop ``layers`` (rows, cols, C) around the agent, rotated so that ahead is up.

        Each crop cell takes the map cell under its centre. At angles other than multiples of
        90° that sampling skips some map cells, so an object (channel 1, one cell each) would
        vanish from the crop at some poses (10 % of poses within 8 m of the goal in the v3 val
        houses): object cells are therefore placed by their centres instead, and never skipped.
        """
        cos, sin = math.cos(yaw), math.sin(yaw)
        x = position[0] + self._forward * cos - self._left * sin
        y = position[1] + self._forward * sin + self._left * cos
        rows, cols = self.coarse_cell(np.stack([x, y], axis=-1))
        ok = (rows >= 0) & (rows < layers.shape[0]) & (cols >= 0) & (cols < layers.shape[1])
        out = np.zeros((*rows.shape, layers.shape[2]), dtype=layers.dtype)
        out[ok] = layers[rows[ok], cols[ok]]
        if layers.shape[2] > 1:
            out[..., 1] = 0
            self._place_objects(out, layers, position, cos, sin)
        return out

    def _place_objects(
        self, out: np.ndarray, layers: np.ndarray, position: np.ndarray, cos: float, sin: float
    ) -> None:
        """Write the object cells of ``layers`` into the crop ``out`` at their centres' cells."""
        rows, cols = np.nonzero(layers[..., 1])
        if rows.size == 0:
            return
        size = self.coarse_size
        dx = self.grid.origin[0] + (cols + 0.5) * size - position[0]
        dy = self.grid.origin[1] + (rows + 0.5) * size - position[1]
        half = self.config.ego_size // 2
        ego_rows = half - np.rint((dx * cos + dy * sin) / size).astype(np.int64)
        ego_cols = half - np.rint((-dx * sin + dy * cos) / size).astype(np.int64)
        inside = (ego_rows >= 0) & (ego_rows < out.shape[0]) & (ego_cols >= 0)
        inside &= ego_cols < out.shape[1]
        out[ego_rows[inside], ego_cols[inside], 1] = layers[rows[inside], cols[inside], 1]


def visible_points(
    grid: NavGrid, position: np.ndarray, yaw: float, fov_deg: float, distance: float, rays: int
) -> np.ndarray:
    """World points (N, 2) the agent sees: a fan of rays stopped by geometry at camera height.

    The first blocked sample of each ray is included: the agent sees the wall it faces.
    """
    half = math.radians(fov_deg) / 2
    angles = yaw + np.linspace(-half, half, rays)
    steps = np.arange(grid.cell_size / 2, distance + 1e-9, grid.cell_size / 2)
    dirs = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    points = position[None, None, :] + steps[None, :, None] * dirs[:, None, :]
    blocked = grid.lookup(grid.view_blocked, points, outside=True)
    blocked_before = np.zeros_like(blocked)
    blocked_before[:, 1:] = np.logical_or.accumulate(blocked, axis=1)[:, :-1]
    return points[~blocked_before]


def can_see(
    grid: NavGrid,
    position: np.ndarray,
    yaw: float,
    target: np.ndarray,
    fov_deg: float,
    distance: float,
) -> bool:
    """Is ``target`` within the field of view and range, with a clear line of sight?"""
    offset = np.asarray(target[:2], dtype=np.float64) - position
    gap = float(np.hypot(*offset))
    if gap > distance:
        return False
    if gap > 1e-9:
        bearing = math.remainder(math.atan2(offset[1], offset[0]) - yaw, 2 * math.pi)
        if abs(bearing) > math.radians(fov_deg) / 2:
            return False
    samples = max(2, int(math.ceil(gap / (grid.cell_size / 2))))
    t = np.linspace(0.0, 1.0, samples, endpoint=False)[:, None]
    points = position[None, :] + t * offset[None, :]
    return not bool(grid.lookup(grid.view_blocked, points, outside=True).any())


class EgoMapReveal:
    """The oracle ego map: oracle-map cells revealed as the agent sees them."""

    def __init__(self, oracle: OracleMap, fov_deg: float) -> None:
        self.oracle = oracle
        self.fov_deg = fov_deg
        self.seen = np.zeros(oracle.layers.shape[:2], dtype=bool)

    def reset(self) -> None:
        self.seen[:] = False

    def update(self, position: np.ndarray, yaw: float) -> None:
        cfg = self.oracle.config
        points = visible_points(
            self.oracle.grid, position, yaw, self.fov_deg, cfg.view_distance, cfg.view_rays
        )
        rows, cols = self.oracle.coarse_cell(points)
        ok = (rows >= 0) & (rows < self.seen.shape[0]) & (cols >= 0) & (cols < self.seen.shape[1])
        self.seen[rows[ok], cols[ok]] = True
        # the agent's own cell is always known
        row, col = self.oracle.coarse_cell(position)
        if 0 <= row < self.seen.shape[0] and 0 <= col < self.seen.shape[1]:
            self.seen[row, col] = True

    def layers(self) -> np.ndarray:
        return np.where(self.seen[..., None], self.oracle.layers, 0).astype(np.uint8)
