"""Oracle maps and visibility (paper §4.2 and supplement).

The global oracle map is a coarse grid (0.8 m cells) with two channels: occupancy
(``MAP_UNKNOWN`` outside the scene, ``MAP_FREE``, ``MAP_OCCUPIED``) and goal category + 1 (0 for
no goal), each goal marked as a ``goal_cells`` × ``goal_cells`` square of cells (3 × 3 by
default). Agents receive an ``ego_size`` × ``ego_size`` crop (50 × 50 by default) rotated to their
heading: row 0 is ahead, column 0 is to the left, and the agent is in cell
``(ego_size // 2, ego_size // 2)``: the centre cell for an odd size; for an even size the cell
just behind and right of the centre point, with ``ego_size / 2`` cells ahead and to the left and
one fewer behind and to the right (cell (25, 25) of the default 50 × 50 crop).

The reference code (saimwani/multiON, ``habitat/core/env.py``) does the same: its global map has
300 × 300 cells over [-120.32, 120.04] m, 0.801 m each (``conv_grid``, lines 214-233); each goal
is written as ``grid_loc ± 1`` (line 279, a 3 × 3 patch); reset and step cut an 80 × 80 patch
around the agent's cell, rotate it by the heading and keep its centre 50 × 50
(``patch[40-25:40+25, 40-25:40+25]``, lines 291-293 and 347-349), which puts the agent at index
25 of the crop; ``policy.py`` reads it as ``MapCNN(50, ...)`` and ``.view(bs, 50, 50, -1)``
(lines 412, 419, 465-466). Our ``oracle_ego_map`` keeps both channels with 0 for unseen cells
(occupancy ``MAP_UNKNOWN``); the reference's OracleEgoMap reads the object channel alone, offset
by one more (1 = seen, no goal; goal category + 2, line 278 and ``mapCache += 1``, lines 137-139),
which carries the same information.

The oracle *ego* map holds only the cells the agent has seen: within the field of view, within
``view_distance``, and not hidden behind geometry at the camera's height (the line of sight is
traced on the fine grid, so walls occlude).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from multion.config.episode import Goal
from multion.config.task import MapConfig
from multion.sim.navgrid import NavGrid
from multion_client.constants import MAP_FREE, MAP_OCCUPIED, MAP_UNKNOWN


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
        """Mark each goal as a ``goal_cells`` square of category + 1, in order (a later goal's
        square covers an earlier one's, as in the reference); then every goal's own cell once
        more, so that no goal loses its centre to a neighbour's square."""
        self.layers[..., 1] = 0
        rows, cols = self.layers.shape[:2]
        half = self.config.goal_cells // 2
        centres = [(self.coarse_cell(np.asarray(g.position[:2])), g.category + 1) for g in goals]
        for (row, col), value in centres:
            r0, r1 = max(0, int(row) - half), min(rows, int(row) + half + 1)
            c0, c1 = max(0, int(col) - half), min(cols, int(col) + half + 1)
            if r0 < r1 and c0 < c1:
                self.layers[r0:r1, c0:c1, 1] = value
        for (row, col), value in centres:
            if 0 <= row < rows and 0 <= col < cols:
                self.layers[row, col, 1] = value

    def coarse_cell(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xy = np.asarray(xy, dtype=np.float64)
        col = np.floor((xy[..., 0] - self.grid.origin[0]) / self.coarse_size).astype(np.int64)
        row = np.floor((xy[..., 1] - self.grid.origin[1]) / self.coarse_size).astype(np.int64)
        return row, col

    def egocentric(self, layers: np.ndarray, position: np.ndarray, yaw: float) -> np.ndarray:
        """Crop ``layers`` (rows, cols, C) around the agent, rotated so that ahead is up.

        Each crop cell takes the map cell under its centre. At angles other than multiples of
        90° that sampling skips some map cells, so an object cell (channel 1) would vanish from
        the crop at some poses (10 % of poses within 8 m of the goal in the v3 val houses, with
        one cell per goal): object cells are therefore placed by their centres instead, and never
        skipped.
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
