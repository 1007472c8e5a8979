"""Distance fields: the sources found in a window equal a scan of the whole grid, and the
cache shared by episode sampling and reset hands out the same, read-only fields."""

from __future__ import annotations

import numpy as np

from multion.sim import geodesic
from multion.sim.geodesic import FieldCache, distance_field
from multion.sim.navgrid import NavGrid


def room_grid(offset: float = 0.0) -> NavGrid:
    navigable = np.zeros((40, 60), dtype=bool)
    navigable[5:35, 5:55] = True
    navigable[5:30, 30] = False  # a wall with a gap at the bottom
    full = np.ones_like(navigable)
    return NavGrid((offset, 0.0), 0.05, 0.0, full, navigable, navigable, ~full)


def scanned_sources(grid: NavGrid, target: np.ndarray, radius: float) -> set[tuple[int, int]]:
    """Every navigable cell's centre tested (the code before issue 30)."""
    rows, cols = np.nonzero(grid.navigable)
    centres = grid.cell_to_world(rows, cols)
    gap = np.hypot(centres[:, 0] - target[0], centres[:, 1] - target[1])
    near = gap <= radius + grid.cell_size / 2
    if not near.any():
        near = gap <= gap.min() + 1e-9
    return set(zip(rows[near].tolist(), cols[near].tolist(), strict=True))


def test_sources_in_a_window_are_the_sources_of_a_full_scan() -> None:
    grid = room_grid(0.013)
    rng = np.random.default_rng(0)
    for _ in range(300):
        target = rng.uniform(-0.3, 3.3, size=2)  # also off the grid and inside the wall
        radius = float(rng.choice([0.0, 0.05, 0.4]))
        rows, cols = geodesic._source_cells(grid, target, radius)
        assert set(zip(rows.tolist(), cols.tolist(), strict=True)) == scanned_sources(
            grid, target, radius
        )


def test_the_field_cache_reuses_fields_per_grid_and_target() -> None:
    grid, other = room_grid(), room_grid(0.5)
    cache = FieldCache(size=2)
    a = cache.get(grid, np.array([0.5, 0.5]), 0.05)
    assert cache.get(grid, np.array([0.5, 0.5]), 0.05) is a
    assert not a.flags.writeable  # no user can change another's field
    assert np.array_equal(a, distance_field(grid, np.array([0.5, 0.5]), 0.05))
    assert cache.get(grid, np.array([0.5, 0.5]), 0.0) is not a  # another radius
    cache.get(grid, np.array([2.0, 0.5]), 0.05)  # a third target evicts the oldest
    assert cache.get(grid, np.array([0.5, 0.5]), 0.05) is not a
    moved = cache.get(other, np.array([2.0, 0.5]), 0.05)  # another grid: computed in it
    assert np.array_equal(moved, distance_field(other, np.array([2.0, 0.5]), 0.05))
