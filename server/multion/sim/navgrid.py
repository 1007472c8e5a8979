"""The navigable grid: where the agent's centre may stand, computed from scene geometry by ray casts.

One code path serves procedural houses and mesh scans alike (SPEC §4):

1. the floor height is the mode of the first surfaces met by short downward rays cast just above
   the lowest surface of the scene (or given);
2. a downward ray per cell from ``floor + agent_height`` tells whether the floor is reached with
   nothing in between (tables, beds, sofas stop it);
3. short horizontal rays across each cell, in the four axis directions, at a few heights, catch
   what the downward ray can miss: walls and tall furniture the ray starts inside of, thin scan
   surfaces. The same test at the camera's height gives the map that blocks the line of sight;
4. free cells are eroded by the agent radius and only the largest connected region is kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from multion.config.sim import NavGridConfig
from multion.sim.world import MeshSceneError, PyBulletWorld

NAVGRID_VERSION = 1
"""Version of :func:`build_navgrid`'s algorithm. Bump it whenever a change alters the cells it
computes: navigable grids cached on disk under an older version are then rebuilt."""


@dataclass
class NavGrid:
    """A top-down grid over the scene. Row ``i`` is ``y = origin_y + (i + 0.5) * cell_size``, column
    ``j`` is ``x = origin_x + (j + 0.5) * cell_size``."""

    origin: tuple[float, float]
    cell_size: float
    floor_z: float
    inside: np.ndarray
    """Some surface lies under this cell (it is part of the scene)."""
    free: np.ndarray
    """Floor with no obstacle up to the agent height, before erosion."""
    navigable: np.ndarray
    """Where the agent centre may stand: free, eroded by the radius, largest connected region."""
    view_blocked: np.ndarray
    """Geometry at the camera height: blocks the line of sight."""

    @property
    def shape(self) -> tuple[int, int]:
        rows, cols = self.navigable.shape
        return rows, cols

    def world_to_cell(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cell indices ``(rows, cols)`` of world points ``xy`` (shape ``(..., 2)``); may be out of range."""
        xy = np.asarray(xy, dtype=np.float64)
        cols = np.floor((xy[..., 0] - self.origin[0]) / self.cell_size).astype(np.int64)
        rows = np.floor((xy[..., 1] - self.origin[1]) / self.cell_size).astype(np.int64)
        return rows, cols

    def cell_to_world(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """World ``(x, y)`` of cell centres."""
        x = self.origin[0] + (np.asarray(cols) + 0.5) * self.cell_size
        y = self.origin[1] + (np.asarray(rows) + 0.5) * self.cell_size
        return np.stack([x, y], axis=-1)

    def lookup(self, grid: np.ndarray, xy: np.ndarray, outside: float | bool = False) -> np.ndarray:
        """Values of ``grid`` at world points ``xy``; ``outside`` where a point is off the grid."""
        rows, cols = self.world_to_cell(xy)
        ok = (rows >= 0) & (rows < grid.shape[0]) & (cols >= 0) & (cols < grid.shape[1])
        out = np.full(rows.shape, outside, dtype=grid.dtype)
        out[ok] = grid[rows[ok], cols[ok]]
        return out

    def is_navigable(self, xy: np.ndarray) -> np.ndarray:
        return self.lookup(self.navigable, xy, outside=False)

    def segment_is_navigable(self, start: np.ndarray, end: np.ndarray) -> bool:
        """True when every point of the straight segment lies on navigable cells.

        Checking the centre line on the eroded grid is checking the agent's whole body sweep.
        """
        length = float(np.hypot(*(np.asarray(end) - np.asarray(start))))
        samples = max(2, int(np.ceil(length / (self.cell_size / 2))) + 1)
        t = np.linspace(0.0, 1.0, samples)[:, None]
        points = (1 - t) * np.asarray(start)[None, :] + t * np.asarray(end)[None, :]
        return bool(self.is_navigable(points).all())


def build_navgrid(world: PyBulletWorld, config: NavGridConfig = NavGridConfig()) -> NavGrid:
    """Compute the navigable grid of the scene loaded in ``world``."""
    low, high = world.bounds()
    cs = config.cell_size
    # cell centres on multiples of the cell size: hand-placed points and 0.25 m steps then fall on
    # centres rather than on boundaries, where float rounding would decide the cell
    origin = (
        float((np.floor((low[0] - config.margin) / cs) - 0.5) * cs),
        float((np.floor((low[1] - config.margin) / cs) - 0.5) * cs),
    )
    cols = int(np.ceil((high[0] + config.margin - origin[0]) / cs))
    rows = int(np.ceil((high[1] + config.margin - origin[1]) / cs))
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    centres = np.stack([origin[0] + (jj + 0.5) * cs, origin[1] + (ii + 0.5) * cs], axis=-1).reshape(
        -1, 2
    )

    floor_z = (
        config.floor_z if config.floor_z is not None else _find_floor(world, centres, low, high)
    )

    # 2. downward rays from head height: the first surface met must be the floor
    top = floor_z + config.agent_height
    bottom = floor_z - 0.5
    starts = np.column_stack([centres, np.full(len(centres), top)])
    ends = np.column_stack([centres, np.full(len(centres), bottom)])
    hit, fraction, _ = world.cast_rays(starts, ends)
    hit_z = top + fraction * (bottom - top)
    inside = _inside_scene(world, centres, low, high)
    floor = hit & (np.abs(hit_z - floor_z) <= config.max_step_height)

    # close one-cell cracks in the floor (slab seams, small holes in scans): rays through them
    # would otherwise cut doors in two once eroded
    floor_map = ndimage.binary_closing(
        floor.reshape(rows, cols), structure=np.ones((3, 3), dtype=bool)
    )
    floor_map &= inside.reshape(rows, cols)

    # 3. short crossing rays per cell, only where they can change the answer
    obstacle = np.zeros(len(centres), dtype=bool)
    candidates = np.flatnonzero(floor_map.ravel())
    for height in config.obstacle_heights:
        obstacle[candidates] |= _crossing_hits(world, centres[candidates], floor_z + height, cs)
    view_blocked = np.zeros(len(centres), dtype=bool)
    in_scene = np.flatnonzero(inside)
    view_blocked[in_scene] = _crossing_hits(
        world, centres[in_scene], floor_z + config.view_height, cs
    )

    free = floor_map & ~obstacle.reshape(rows, cols)
    # 4. erosion by the agent radius, then the largest 8-connected region
    clearance = ndimage.distance_transform_edt(free) * cs
    eroded = clearance >= config.agent_radius - 1e-9
    labels, count = ndimage.label(eroded, structure=np.ones((3, 3), dtype=int))
    if count == 0:
        raise MeshSceneError(
            "the scene has no navigable floor for the agent (is it a single-floor indoor scene?)"
        )
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    navigable = labels == int(np.argmax(sizes))
    return NavGrid(
        origin=origin,
        cell_size=cs,
        floor_z=float(floor_z),
        inside=inside.reshape(rows, cols),
        free=free,
        navigable=navigable,
        view_blocked=view_blocked.reshape(rows, cols),
    )


def _crossing_hits(
    world: PyBulletWorld, centres: np.ndarray, z: float, cell_size: float
) -> np.ndarray:
    """True for cells crossed by geometry at height ``z``: four short rays per cell (±x, ±y).

    Rays in both directions matter: a ray that starts inside a box does not report that box.
    """
    n = len(centres)
    if n == 0:
        return np.zeros(0, dtype=bool)
    half = cell_size / 2
    result = np.zeros(n, dtype=bool)
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        offset = np.array([dx * half, dy * half])
        starts = np.column_stack([centres - offset, np.full(n, z)])
        ends = np.column_stack([centres + offset, np.full(n, z)])
        hit, _, _ = world.cast_rays(starts, ends)
        result |= hit
    return result


def _inside_scene(
    world: PyBulletWorld, centres: np.ndarray, low: np.ndarray, high: np.ndarray
) -> np.ndarray:
    """Cells with any surface below them: rays cast upwards from under the whole scene."""
    starts = np.column_stack([centres, np.full(len(centres), low[2] - 0.1)])
    ends = np.column_stack([centres, np.full(len(centres), high[2] + 0.1)])
    hit, _, _ = world.cast_rays(starts, ends)
    return hit


def _find_floor(
    world: PyBulletWorld, centres: np.ndarray, low: np.ndarray, high: np.ndarray
) -> float:
    """The floor height: the most common top surface just above the lowest geometry.

    Upward rays from below the scene find the lowest surface of each column (the floor itself for
    a scan, the underside of a slab for boxes); short downward rays from 0.3 m above it then meet
    the walkable top surface. The mode over a sample of columns is the floor.
    """
    sample = centres[:: max(1, len(centres) // 20_000)]
    starts = np.column_stack([sample, np.full(len(sample), low[2] - 0.1)])
    ends = np.column_stack([sample, np.full(len(sample), high[2] + 0.1)])
    hit, fraction, _ = world.cast_rays(starts, ends)
    if not hit.any():
        raise MeshSceneError("no floor found: no surface under the scene")
    lowest = starts[hit, 2] + fraction[hit] * (ends[hit, 2] - starts[hit, 2])
    tops = lowest + 0.3
    down_starts = np.column_stack([sample[hit], tops])
    down_ends = np.column_stack([sample[hit], lowest - 0.01])
    hit2, fraction2, normal2 = world.cast_rays(down_starts, down_ends)
    up_facing = hit2 & (normal2[:, 2] > 0.7)
    if not up_facing.any():
        raise MeshSceneError(
            "no floor found: no upward-facing surface near the bottom of the scene"
        )
    z = down_starts[up_facing, 2] + fraction2[up_facing] * (
        down_ends[up_facing, 2] - down_starts[up_facing, 2]
    )
    # mode at 1 cm resolution
    bins = np.round(z / 0.01).astype(np.int64)
    values, counts = np.unique(bins, return_counts=True)
    return float(values[np.argmax(counts)] * 0.01)
