"""Discs of cells and boxes of cells on the explorer's start-frame grid.

The explorer marks and reads discs round points (where it gave a frontier up, the cells near
its path, the ring round a goal) and keeps its plans to boxes round what it knows. A box is
``(row0, row1, col0, col1)`` with exclusive ends; ``row0 >= row1`` is the empty box.
"""

from __future__ import annotations

import math

import numpy as np

from multion_agents.baselines.navigation import StartFrameGrid

Box = tuple[int, int, int, int]


class GridDiscs:
    """Discs of cells within a radius of a point's cell; each radius's mask is built once."""

    def __init__(self, grid: StartFrameGrid) -> None:
        self.grid = grid
        self._masks: dict[float, np.ndarray] = {}  # radius → disc of cells round (0, 0)

    def window(self, centre: np.ndarray, radius: float) -> tuple[int, int, int, int, np.ndarray]:
        """The cells within ``radius`` of ``centre``'s cell, as a box (row0, row1, col0, col1)
        on the grid and the disc's mask inside it (clipped at the grid's edges)."""
        size, cell_size = self.grid.size, self.grid.cell_size
        cells = int(math.ceil(radius / cell_size))
        whole = self._masks.get(radius)
        if whole is None:
            rr, cc = np.mgrid[-cells : cells + 1, -cells : cells + 1]
            whole = self._masks[radius] = np.hypot(rr, cc) * cell_size <= radius
        row, col = (int(v) for v in self.grid.to_cell(centre))
        r0, r1 = max(0, row - cells), min(size, row + cells + 1)
        c0, c1 = max(0, col - cells), min(size, col + cells + 1)
        r1, c1 = max(r0, r1), max(c0, c1)
        mask = whole[r0 - row + cells : r1 - row + cells, c0 - col + cells : c1 - col + cells]
        return r0, r1, c0, c1, mask

    def disc(self, centre: np.ndarray, radius: float) -> np.ndarray:
        """The disc as a mask of the whole grid."""
        mask = np.zeros((self.grid.size, self.grid.size), dtype=bool)
        r0, r1, c0, c1, inside = self.window(centre, radius)
        mask[r0:r1, c0:c1] = inside
        return mask

    def paint(self, layer: np.ndarray, centre: np.ndarray, radius: float, value: bool) -> None:
        """Set the cells of a disc to ``value`` in ``layer``, touching only the disc's box."""
        r0, r1, c0, c1, inside = self.window(centre, radius)
        layer[r0:r1, c0:c1][inside] = value

    def box(self, centre: np.ndarray, radius: float) -> Box:
        """The box round the disc's cells (empty where the disc is off the grid)."""
        r0, _, c0, _, inside = self.window(centre, radius)
        rows, cols = np.nonzero(inside)
        if len(rows) == 0:
            return self.grid.size, 0, self.grid.size, 0
        return (
            r0 + int(rows.min()),
            r0 + int(rows.max()) + 1,
            c0 + int(cols.min()),
            c0 + int(cols.max()) + 1,
        )


def box_union(a: Box, b: Box) -> Box:
    """The box round two boxes; empty ones ignored."""
    if a[0] >= a[1]:
        return b
    if b[0] >= b[1]:
        return a
    return min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3])


def box_grown(box: Box, margin: int, size: int) -> Box:
    """``box`` grown by ``margin`` cells and clipped to the grid, as
    :func:`~.navigation.bounding_box` does (the whole grid for an empty box)."""
    r0, r1, c0, c1 = box
    if r0 >= r1:
        return 0, size, 0, size
    return max(0, r0 - margin), min(size, r1 + margin), max(0, c0 - margin), min(size, c1 + margin)
