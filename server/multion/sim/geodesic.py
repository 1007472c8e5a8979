"""Geodesic distances on the navigable grid by fast marching (scikit-fmm).

A distance field is computed once per goal per episode; every step then reads it in O(1).
"""

from __future__ import annotations

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
    rows, cols = np.nonzero(nav)
    centres = grid.cell_to_world(rows, cols)
    gap = np.hypot(centres[:, 0] - target[0], centres[:, 1] - target[1])
    sources = gap <= target_radius + grid.cell_size / 2
    if not sources.any():
        sources = gap <= gap.min() + 1e-9
    phi = np.ones(nav.shape)
    phi[rows[sources], cols[sources]] = -1.0
    field = skfmm.distance(np.ma.MaskedArray(phi, mask=~nav), dx=grid.cell_size)
    # fast marching measures from the zero level set, half a cell outside the source cells
    distance = np.asarray(field.filled(np.inf), dtype=np.float64)
    distance = np.where(distance < 0, 0.0, distance + grid.cell_size / 2)
    distance[phi < 0] = 0.0
    distance[~nav] = np.inf
    return distance


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
