"""Oracle maps and visibility (paper §4.2 and supplement).

The global oracle map is a coarse grid (0.8 m cells) with two channels: occupancy
(``MAP_UNKNOWN`` outside the scene, ``MAP_FREE``, ``MAP_OCCUPIED``) and goal category + 1 (0 for
no goal), each goal marked as a ``goal_cells`` × ``goal_cells`` square of cells (3 × 3 by
default). Agents receive an ``ego_size`` × ``ego_size`` crop (50 × 50 by default) rotated to their
heading: row 0 is ahead, column 0 is to the left, and the agent is in cell
``(ego_size // 2, ego_size // 2)``: the centre cell for an odd size; for an even size the cell
just behind and right of the centre point, with ``ego_size / 2`` cells ahead and to the left and
one fewer behind and to the right (cell (25, 25) of the default 50 × 50 crop).

The reference code (saimwani/multiON at 2ba4d25, ``habitat/core/env.py``) cuts the same kind
of crop from the same kind of map, but not the same crop. Its global map has 300 × 300 cells
over [-120.32, 120.04] m, 0.801 m each, whose rows run along -x and columns along +z (habitat's
y-up frame: our -y), ``conv_grid``, l. 214-233; each goal is written as ``grid_loc ± 1``
(l. 279, a 3 × 3 patch). Reset and step cut an 80 × 80 patch around the agent's cell, rotate it
with ``ndimage.rotate(patch, -(heading°) + 90, order=0, reshape=False)`` and keep its centre
50 × 50 (``patch[40-25:40+25, 40-25:40+25]``, l. 291-293 and 347-349); ``policy.py`` reads it as
``MapCNN(50, ...)`` and ``.view(bs, 50, 50, -1)`` (l. 412, 419, 465-466). Habitat's heading is
our yaw - 90° (0 looks along habitat's -z, our +y). How our crop (``maps.convention =
"project"``, the default, which this project's agents and checkpoints read) differs:

* orientation: in the reference's crop ahead is *down* and the agent's left is to the *right*:
  ours turned by 180°;
* agent cell: the reference rotates about the patch's centre point, the corner between four
  cells up and left of the agent's cell, so the agent's cell moves between (24|25, 24|25) with the
  heading; ours is always (25, 25), and our crop turns about the agent's position, not a corner;
* sampling: the reference takes each crop cell's nearest patch cell, so at angles other than
  multiples of 90° goal cells can vanish from its crop or double; ours places goal cells by their
  centres and never drops one (:meth:`OracleMap.egocentric`);
* values: both write occupancy and goal category + 1 (l. 278); the reference's OracleEgoMap adds
  one more to every seen cell (``mapCache += 1``, l. 137-139: occupancy + 1, 1 for no goal, goal
  category + 2) and 0 for unseen ones, where ours keeps the oracle map's values on seen cells and 0
  (occupancy ``MAP_UNKNOWN``) on unseen ones;
* category ids: ours are this project's, the reference's its colour order (l. 252-253).

``maps.convention = "reference"`` makes both oracle sensors the reference's crop and values
(:func:`reference_crop`, :meth:`EgoMapReveal.layers`), in this project's category ids:
``multion_client.semantic_map`` renumbers them into habitat agents' ``semMap``.

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
from multion_client.semantic_map import REFERENCE_CONVENTION


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
        self.coarse_size = factor * grid.cell_size
        # The reference writes whole goal squares, past the scene's edge too (its map spans
        # ±120 m): under its convention the map gets a margin of unknown cells to hold them.
        margin = config.goal_cells // 2 if config.convention == REFERENCE_CONVENTION else 0
        # the world corner (metres) of cell (0, 0)
        self.origin = np.asarray(grid.origin, dtype=np.float64) - margin * self.coarse_size
        self.layers = np.zeros((rows + 2 * margin, cols + 2 * margin, 2), dtype=np.uint8)
        self.layers[margin : margin + rows, margin : margin + cols, 0] = occupancy
        half = config.ego_size // 2
        r, c = np.meshgrid(np.arange(config.ego_size), np.arange(config.ego_size), indexing="ij")
        self._forward = (half - r).astype(np.float64) * self.coarse_size
        self._left = (half - c).astype(np.float64) * self.coarse_size

    def set_goals(self, goals: Sequence[Goal]) -> None:
        """Mark each goal as a ``goal_cells`` square of category + 1, in order (a later goal's
        square covers an earlier one's, as in the reference); then, in the project convention,
        every goal's own cell once more, so that no goal loses its centre to a neighbour's square
        (the reference, ``habitat/core/env.py`` l. 274-279, does not)."""
        self.layers[..., 1] = 0
        rows, cols = self.layers.shape[:2]
        half = self.config.goal_cells // 2
        centres = [(self.coarse_cell(np.asarray(g.position[:2])), g.category + 1) for g in goals]
        for (row, col), value in centres:
            r0, r1 = max(0, int(row) - half), min(rows, int(row) + half + 1)
            c0, c1 = max(0, int(col) - half), min(cols, int(col) + half + 1)
            if r0 < r1 and c0 < c1:
                self.layers[r0:r1, c0:c1, 1] = value
        if self.config.convention == REFERENCE_CONVENTION:
            return
        for (row, col), value in centres:
            if 0 <= row < rows and 0 <= col < cols:
                self.layers[row, col, 1] = value

    def coarse_cell(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xy = np.asarray(xy, dtype=np.float64)
        col = np.floor((xy[..., 0] - self.origin[0]) / self.coarse_size).astype(np.int64)
        row = np.floor((xy[..., 1] - self.origin[1]) / self.coarse_size).astype(np.int64)
        return row, col

    def egocentric(self, layers: np.ndarray, position: np.ndarray, yaw: float) -> np.ndarray:
        """Crop ``layers`` (rows, cols, C) around the agent, rotated so that ahead is up (the
        reference's crop, ahead down, under ``maps.convention = "reference"``).

        Each crop cell takes the map cell under its centre. At angles other than multiples of
        90° that sampling skips some map cells, so an object cell (channel 1) would vanish from
        the crop at some poses (10 % of poses within 8 m of the goal in the v3 val houses, with
        one cell per goal): object cells are therefore placed by their centres instead, and never
        skipped.
        """
        if self.config.convention == REFERENCE_CONVENTION:
            row, col = self.coarse_cell(position)
            return reference_crop(layers, (int(row), int(col)), yaw, self.config.ego_size)
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
        dx = self.origin[0] + (cols + 0.5) * size - position[0]
        dy = self.origin[1] + (rows + 0.5) * size - position[1]
        half = self.config.ego_size // 2
        ego_rows = half - np.rint((dx * cos + dy * sin) / size).astype(np.int64)
        ego_cols = half - np.rint((-dx * sin + dy * cos) / size).astype(np.int64)
        inside = (ego_rows >= 0) & (ego_rows < out.shape[0]) & (ego_cols >= 0)
        inside &= ego_cols < out.shape[1]
        out[ego_rows[inside], ego_cols[inside], 1] = layers[rows[inside], cols[inside], 1]


def reference_crop(
    layers: np.ndarray, agent_cell: tuple[int, int], yaw: float, size: int
) -> np.ndarray:
    """The reference's crop (``habitat/core/env.py`` l. 291-293) of ``layers`` (rows along +y,
    columns along +x) for an agent in cell ``agent_cell`` (row, col) facing ``yaw``.

    As the reference: the map seen with rows along -x and columns along +z (our -y), the pivot at
    the agent's cell, each crop cell the nearest cell of the map turned by ``-heading° + 90``
    about the crop's centre point, cells beyond the map 0. ``ndimage.rotate(..., order=0,
    reshape=False)`` maps output cell ``o`` to ``M (o - c) + c`` with ``M = [[cos, sin], [-sin,
    cos]]``, ``c`` the patch's centre, and rounds half up (``floor(x + 0.5)``): the same
    arithmetic here, without the 80-cell patch (which covers every cell of the 50-cell crop:
    its corners are 34.6 cells from the centre, the patch's edge 39.5), so any ``size`` works;
    for an odd ``size`` the turn is about the agent's cell.
    """
    in_reference_axes = layers.transpose(1, 0, 2)[::-1, ::-1]  # rows along -x, columns along -y
    pivot_row = layers.shape[1] - 1 - agent_cell[1]
    pivot_col = layers.shape[0] - 1 - agent_cell[0]
    heading = math.remainder(yaw - math.pi / 2, 2 * math.pi)  # habitat's HeadingSensor
    angle = math.radians(-math.degrees(heading) + 90)
    cos, sin = math.cos(angle), math.sin(angle)
    centre = (size - 1) / 2
    r, c = np.meshgrid(np.arange(size) - centre, np.arange(size) - centre, indexing="ij")
    rows = np.floor(cos * r + sin * c + centre + 0.5).astype(np.int64) + pivot_row - size // 2
    cols = np.floor(-sin * r + cos * c + centre + 0.5).astype(np.int64) + pivot_col - size // 2
    height, width = in_reference_axes.shape[:2]
    inside = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)
    out = np.zeros((size, size, layers.shape[2]), dtype=layers.dtype)
    out[inside] = in_reference_axes[rows[inside], cols[inside]]
    return out


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
    visible: np.ndarray = points[~blocked_before]
    return visible


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
        """The oracle map where seen, 0 elsewhere; under the reference convention the map + 1
        where seen (the reference's ``mapCache += 1``, ``habitat/core/env.py`` l. 137-139)."""
        seen_value = self.oracle.layers
        if self.oracle.config.convention == REFERENCE_CONVENTION:
            seen_value = seen_value + 1
        return np.where(self.seen[..., None], seen_value, 0).astype(np.uint8)


class PoseCrops:
    """The oracle maps cut around one pose: what the oracle map sensors read at one step
    (:class:`multion.task.sensors.OracleCrops`)."""

    def __init__(
        self, oracle: OracleMap, reveal: EgoMapReveal, position: np.ndarray, yaw: float
    ) -> None:
        self.oracle, self.reveal = oracle, reveal
        self.position, self.yaw = position, yaw

    def full(self) -> np.ndarray:
        return self.oracle.egocentric(self.oracle.layers, self.position, self.yaw)

    def revealed(self) -> np.ndarray:
        """The ego map: what is seen from this pose is revealed first (once per step: only the
        ``oracle_ego_map`` sensor asks)."""
        self.reveal.update(self.position, self.yaw)
        return self.oracle.egocentric(self.reveal.layers(), self.position, self.yaw)
