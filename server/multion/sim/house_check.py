"""Is a procedural house sound? Invariants of its geometry and of its navigable grid (issue 33).

Small houses once had a roof three times the size of their one room; the navigable grid took
the roof for the floor, so agents started on sofas and walked through walls. These checks catch
that class of fault: the property test runs them over the generator's range and
``multion leaderboard check --generate`` refuses a challenge whose hidden houses fail them.

Geometry: every floor slab lies under a room (or its walls), every room is closed by walls
except at its doors, furniture stays inside rooms, the roof is not much larger than the floor.
Grid: it stands on the layout's floor, covers at most the footprint, and every navigable cell is
inside a room or a doorway and clear of walls and furniture by the agent's radius.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import numpy.typing as npt

from multion.scenes.layout import Box, Door, SceneLayout
from multion.sim.navgrid import NavGrid

MIN_FLOOR_UNDER_ROOF = 0.6
"""The floor slabs cover at least this share of the roof (cut corners leave roof over nothing)."""
EPS = 1e-6
Rect = tuple[float, float, float, float]


def _rect(box: Box) -> Rect:
    (x0, y0, _), (x1, y1, _) = box.min_corner, box.max_corner
    return (x0, y0, x1, y1)


def _area(r: Rect) -> float:
    return max(r[2] - r[0], 0.0) * max(r[3] - r[1], 0.0)


def _grown(r: Rect, by: float) -> Rect:
    return (r[0] - by, r[1] - by, r[2] + by, r[3] + by)


def _within(inner: Rect, outer: Rect) -> bool:
    return all(inner[k] >= outer[k] - EPS for k in (0, 1)) and all(
        inner[k] <= outer[k] + EPS for k in (2, 3)
    )


def _door_rect(door: Door, depth: float) -> Rect:
    """The gap a door cuts through its wall, ``depth`` deep across the wall."""
    (cx, cy), half = door.center, door.width / 2
    if door.axis == "x":
        return (cx - half, cy - depth, cx + half, cy + depth)
    return (cx - depth, cy - half, cx + depth, cy + half)


def _in_any(rects: Iterable[Rect], xy: np.ndarray) -> np.ndarray:
    inside = np.zeros(len(xy), dtype=bool)
    for x0, y0, x1, y1 in rects:
        inside |= (
            (xy[:, 0] >= x0 - EPS) & (xy[:, 0] <= x1 + EPS)
            & (xy[:, 1] >= y0 - EPS) & (xy[:, 1] <= y1 + EPS)
        )  # fmt: skip
    return inside


def _distance_to(rect: Rect, xy: np.ndarray) -> np.ndarray:
    dx = np.maximum(np.maximum(rect[0] - xy[:, 0], xy[:, 0] - rect[2]), 0.0)
    dy = np.maximum(np.maximum(rect[1] - xy[:, 1], xy[:, 1] - rect[3]), 0.0)
    return np.hypot(dx, dy)


def geometry_problems(layout: SceneLayout, wall_thickness: float = 0.15) -> list[str]:
    """What is wrong with a house's boxes and rooms (empty when it is sound)."""
    problems: list[str] = []
    t = wall_thickness
    rooms = [r.rect for r in layout.rooms]
    cells = [_grown(r, t) for r in rooms]  # a room, its walls and the outer half of outer walls
    floors = [_rect(b) for b in layout.boxes if b.kind == "floor"]
    walls = [_rect(b) for b in layout.boxes if b.kind == "wall"]
    for f in floors:
        if not any(_within(f, c) for c in cells):
            problems.append(f"floor slab {f} is not under any room")
    roof = sum(_area(_rect(b)) for b in layout.boxes if b.kind == "ceiling")
    floor_area = sum(_area(f) for f in floors)
    if roof > 0 and floor_area < MIN_FLOOR_UNDER_ROOF * roof:
        problems.append(
            f"the floor covers {100 * floor_area / roof:.0f} % of the roof (at least "
            f"{100 * MIN_FLOOR_UNDER_ROOF:.0f} %)"
        )
    for i, (x0, y0, x1, y1) in enumerate(rooms):
        # points along the room's outline, half a wall outside it: a wall or one of its doors
        step = 0.05
        xs = np.arange(x0 + step / 2, x1, step)
        ys = np.arange(y0 + step / 2, y1, step)
        ring = np.concatenate([
            np.column_stack([xs, np.full(len(xs), y0 - t / 2)]),
            np.column_stack([xs, np.full(len(xs), y1 + t / 2)]),
            np.column_stack([np.full(len(ys), x0 - t / 2), ys]),
            np.column_stack([np.full(len(ys), x1 + t / 2), ys]),
        ])  # fmt: skip
        gaps = [_door_rect(d, t) for d in layout.doors if i in d.rooms]
        open_points = ~(_in_any(walls, ring) | _in_any(gaps, ring))
        if open_points.any():
            x, y = ring[int(np.argmax(open_points))]
            problems.append(f"room {i} has no wall at ({x:.2f}, {y:.2f})")
    for b in layout.boxes:
        if b.kind == "furniture" and not any(_within(_rect(b), r) for r in rooms):
            problems.append(f"furniture at {b.center[:2]} stands outside every room")
    return problems


def grid_problems(
    layout: SceneLayout, grid: NavGrid, agent_radius: float = 0.1, agent_height: float = 1.5
) -> list[str]:
    """What is wrong with a house's navigable grid (empty when it is sound)."""
    problems: list[str] = []
    if abs(grid.floor_z - layout.floor_z) > 1e-6:
        problems.append(f"the grid stands at z = {grid.floor_z:g}, the floor at {layout.floor_z:g}")
    navigable = float(grid.navigable.sum()) * grid.cell_size**2
    footprint = float(layout.metadata.get("footprint_area", 0.0)) or sum(
        _area(r.rect) for r in layout.rooms
    )
    if navigable > footprint:
        problems.append(f"navigable {navigable:.1f} m² exceeds the footprint's {footprint:.1f} m²")
    rows, cols = np.nonzero(grid.navigable)
    xy = grid.cell_to_world(rows, cols)
    places = [r.rect for r in layout.rooms] + [_door_rect(d, 0.15) for d in layout.doors]
    outside = ~_in_any(places, xy)
    if outside.any():
        x, y = xy[int(np.argmax(outside))]
        problems.append(
            f"{int(outside.sum())} navigable cells outside rooms, e.g. ({x:.2f}, {y:.2f})"
        )
    # a cell centre may sit up to a cell off the exact boundary of the eroded free space
    clearance = agent_radius - grid.cell_size
    for b in layout.boxes:
        low, high = b.min_corner[2] - layout.floor_z, b.max_corner[2] - layout.floor_z
        blocking = b.kind == "wall" or (
            b.kind == "furniture" and low < agent_height and high > 0.05
        )
        if blocking and len(xy):
            near = _distance_to(_rect(b), xy) < clearance
            if near.any():
                x, y = xy[int(np.argmax(near))]
                problems.append(f"navigable cell ({x:.2f}, {y:.2f}) on or next to a {b.kind}")
    return problems


def points_outside_rooms(layout: SceneLayout, points: npt.ArrayLike) -> np.ndarray:
    """For world points (n, 2), True where a point is neither in a room nor in a doorway."""
    places = [r.rect for r in layout.rooms] + [_door_rect(d, 0.15) for d in layout.doors]
    return ~_in_any(places, np.asarray(points, dtype=float).reshape(-1, 2))
