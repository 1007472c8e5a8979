"""Geodesic distances on the navigable grid by fast marching (scikit-fmm).

A distance field is computed once per goal per episode; every step then reads it in O(1).
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
import skfmm

from multion.sim.navgrid import NavGrid


def distance_field(grid: NavGrid, target: np.ndarray, target_radius: float = 0.0) -> np.ndarray:
    """Geodesic distance (metres) from every cell to the nearest navigable point of a disc.

    The disc is centred at ``target`` (world ``(x, y)``) with radius ``target_radius`` (a goal's
    footprint). When no navigable cell lies in it, the nearest navigable cell stands in, so a goal
    placed against a wall still has a distance. Unreachable and non-navigable cells are ``inf``.
    """
    nav = grid.navigable
    phi = np.ones(nav.shape)
    phi[_source_cells(grid, np.asarray(target, dtype=np.float64), target_radius)] = -1.0
    field = skfmm.distance(np.ma.MaskedArray(phi, mask=~nav), dx=grid.cell_size)
    # fast marching measures from the zero level set, half a cell outside the source cells
    distance = np.asarray(field.filled(np.inf), dtype=np.float64)
    distance = np.where(distance < 0, 0.0, distance + grid.cell_size / 2)
    distance[phi < 0] = 0.0
    distance[~nav] = np.inf
    return distance


def _source_cells(
    grid: NavGrid, target: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, cols)`` of the navigable cells whose centres lie within ``radius`` plus half a
    cell of ``target``; when there are none, of the nearest navigable cells. Looked for in a
    window around the target first (a full scan of the grid cost a tenth of a field)."""
    nav = grid.navigable
    within = radius + grid.cell_size / 2
    low = grid.world_to_cell(target - within - grid.cell_size)
    high = grid.world_to_cell(target + within + grid.cell_size)
    r0, c0 = max(0, int(low[0])), max(0, int(low[1]))
    r1, c1 = min(nav.shape[0], int(high[0]) + 1), min(nav.shape[1], int(high[1]) + 1)
    if r0 < r1 and c0 < c1:
        rows, cols = np.nonzero(nav[r0:r1, c0:c1])
        rows, cols = rows + r0, cols + c0
        centres = grid.cell_to_world(rows, cols)
        near = np.hypot(centres[:, 0] - target[0], centres[:, 1] - target[1]) <= within
        if near.any():
            return rows[near], cols[near]
    rows, cols = np.nonzero(nav)
    centres = grid.cell_to_world(rows, cols)
    gap = np.hypot(centres[:, 0] - target[0], centres[:, 1] - target[1])
    sources = gap <= within
    if not sources.any():
        sources = gap <= gap.min() + 1e-9
    return rows[sources], cols[sources]


class FieldCache:
    """The distance fields of the last few targets in one grid, shared by episode sampling and
    the env's reset: a sampled episode's goal fields are the ones its reset needs. Fields are
    read-only, so no user can change another's."""

    def __init__(self, size: int = 8) -> None:
        self.size = size
        self._grid: NavGrid | None = None
        self._fields: OrderedDict[tuple[float, float, float], np.ndarray] = OrderedDict()

    def get(self, grid: NavGrid, target: np.ndarray, target_radius: float = 0.0) -> np.ndarray:
        """:func:`distance_field`, computed only for a grid or target not seen recently."""
        if grid is not self._grid:
            self._grid = grid
            self._fields.clear()
        key = (float(target[0]), float(target[1]), float(target_radius))
        field = self._fields.get(key)
        if field is None:
            field = distance_field(grid, target, target_radius)
            field.flags.writeable = False
            self._fields[key] = field
            if len(self._fields) > self.size:
                self._fields.popitem(last=False)
        else:
            self._fields.move_to_end(key)
        return field

    def put(
        self, grid: NavGrid, target: np.ndarray, target_radius: float, field: np.ndarray
    ) -> None:
        """Keep a field made elsewhere (a goal site's, :mod:`multion.task.goal_sites`): it must
        be :func:`distance_field` of the same arguments, which :meth:`get` then returns."""
        if grid is not self._grid:
            self._grid = grid
            self._fields.clear()
        key = (float(target[0]), float(target[1]), float(target_radius))
        field.flags.writeable = False
        self._fields[key] = field
        self._fields.move_to_end(key)
        if len(self._fields) > self.size:
            self._fields.popitem(last=False)


def geodesic_distance(grid: NavGrid, field: np.ndarray, xy: np.ndarray) -> float:
    """Read ``field`` at a world point (``inf`` off the grid)."""
    return float(grid.lookup(field, np.asarray(xy, dtype=np.float64), outside=np.inf))


def shortest_path(
    grid: NavGrid, field: np.ndarray, start: np.ndarray, max_points: int = 20_000
) -> np.ndarray:
    """Descend ``field`` from ``start`` to its source: world points of a shortest path.

    Steps to the 8-neighbour with the smallest distance; used for pictures and planners.
    """
    row, col = (int(v) for v in grid.world_to_cell(np.asarray(start)))
    if not (0 <= row < field.shape[0] and 0 <= col < field.shape[1]) or not np.isfinite(
        field[row, col]
    ):
        return np.asarray([start], dtype=np.float64)
    padded = np.pad(field, 1, constant_values=np.inf)
    offsets = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]
    cells = [(row, col)]
    for _ in range(max_points):
        if field[row, col] <= 0.0:
            break
        best = min(offsets, key=lambda o: padded[row + 1 + o[0], col + 1 + o[1]])
        if padded[row + 1 + best[0], col + 1 + best[1]] >= field[row, col]:
            break
        row, col = row + best[0], col + best[1]
        cells.append((row, col))
    rows, cols = np.array(cells).T
    return grid.cell_to_world(rows, cols)
