"""Floor plans: cutting a footprint into rooms and corridors, and choosing the doors between them.

Everything is in integer steps of ``grid`` metres (so "do these cells touch?" is exact) and all
randomness comes from the caller's ``numpy.random.Generator``.

1. The rectangular footprint is split recursively (binary space partition), always cutting a cell
   across its longer side. A long cell may instead be cut *along* its length into two rooms with
   a corridor between them: the corridor runs the cell's whole length, and it is never split again.
2. A few corner cells may then be removed, so the footprint is L-, T- or U-shaped; a removal is
   kept only if the remaining cells are still connected through shared walls.
3. Cells sharing at least ``min_shared_wall`` of wall are neighbours. A random spanning tree of
   neighbours gets doors (so every room is reachable; rooms on one tree branch are dead ends), a
   few extra doors make loops, and some doors are *openings* as wide as the shared wall: two
   cells joined that way read as one L-shaped or open-plan room.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from multion.config.scenes import PlanConfig
from multion.scenes.layout import Door

Cell = tuple[int, int, int, int]  # (x0, y0, x1, y1) in grid steps
MIN_KEPT_SHARE = 0.6
"""Corner cuts must leave at least this share of the footprint's rectangle (the ceiling spans
the whole rectangle). Houses of few rooms drew cuts that left one room in a plate three times its
size: the navigable grid then took the roof for the floor (issue 33). Every default house keeps
more than 70 %, so none of them changes."""


@dataclass(frozen=True)
class Plan:
    """Cells of a floor plan (sorted), which of them are corridors, and the doors."""

    cells: tuple[Cell, ...]
    corridors: frozenset[int]
    doors: tuple[Door, ...]
    width: int
    depth: int


def units(metres: float, grid: float) -> int:
    return int(math.ceil(metres / grid - 1e-9))


def _cut(rng: np.random.Generator, length: int, low: int, cfg: PlanConfig) -> int | None:
    lo = max(math.ceil(cfg.split_fraction[0] * length), low)
    hi = min(math.floor(cfg.split_fraction[1] * length), length - low)
    return int(rng.integers(lo, hi + 1)) if lo <= hi else None


def split_cells(
    rng: np.random.Generator, width: int, depth: int, n: int, cfg: PlanConfig
) -> tuple[list[Cell], set[int]] | None:
    """Cut the footprint into ``n`` cells (corridors included), or None if this attempt is stuck."""
    g, t = cfg.grid, cfg.wall_thickness
    min_side = units(cfg.min_room_side + t, g)
    long_enough = units(cfg.corridor_min_length, g)
    cells: list[Cell] = [(0, 0, width, depth)]
    corridor: list[bool] = [False]
    while len(cells) < n:
        splittable = [
            i for i, c in enumerate(cells)
            if not corridor[i] and max(c[2] - c[0], c[3] - c[1]) >= 2 * min_side
        ]  # fmt: skip
        if not splittable:
            return None
        # Prefer big cells so rooms end up of similar size.
        weights = np.array([float(_area(cells[i])) ** 2 for i in splittable])
        index = splittable[int(rng.choice(len(splittable), p=weights / weights.sum()))]
        x0, y0, x1, y1 = cells[index]
        along_x = (x1 - x0) >= (y1 - y0)
        length, across = (x1 - x0, y1 - y0) if along_x else (y1 - y0, x1 - x0)
        cw = units(float(rng.uniform(*cfg.corridor_width)) + t, g)
        corridor_here = (
            len(cells) + 2 <= n
            and sum(corridor) < cfg.max_corridors
            and length >= long_enough
            and across >= 2 * min_side + cw
            and rng.random() < cfg.corridor_probability
        )
        del cells[index], corridor[index]
        if corridor_here:  # two rooms with a corridor between them, along the long side
            a = int(rng.integers(min_side, across - min_side - cw + 1))
            b = a + cw
            if along_x:
                parts = [(x0, y0, x1, y0 + a), (x0, y0 + a, x1, y0 + b), (x0, y0 + b, x1, y1)]
            else:
                parts = [(x0, y0, x0 + a, y1), (x0 + a, y0, x0 + b, y1), (x0 + b, y0, x1, y1)]
            cells += parts
            corridor += [False, True, False]
            continue
        cut = _cut(rng, length, min_side, cfg)
        if cut is None:
            return None
        if along_x:
            cells += [(x0, y0, x0 + cut, y1), (x0 + cut, y0, x1, y1)]
        else:
            cells += [(x0, y0, x1, y0 + cut), (x0, y0 + cut, x1, y1)]
        corridor += [False, False]
    order = sorted(range(len(cells)), key=lambda i: (cells[i][1], cells[i][0]))
    return [cells[i] for i in order], {k for k, i in enumerate(order) if corridor[i]}


def _area(c: Cell) -> int:
    return (c[2] - c[0]) * (c[3] - c[1])


def neighbours(cells: list[Cell], cfg: PlanConfig) -> list[tuple[int, int, str, int, int, int]]:
    """Pairs sharing enough wall: ``(i, j, axis, line, start, end)`` in grid steps.

    ``axis`` is the direction the shared wall runs in: "y" for a wall at ``x = line``.
    """
    pairs = []
    need = cfg.min_shared_wall / cfg.grid - 1e-9
    for i, a in enumerate(cells):
        for j, b in enumerate(cells):
            if a[2] == b[0]:  # b is east of a
                start, end = max(a[1], b[1]), min(a[3], b[3])
                if end - start >= need:
                    pairs.append((i, j, "y", a[2], start, end))
            if a[3] == b[1]:  # b is north of a
                start, end = max(a[0], b[0]), min(a[2], b[2])
                if end - start >= need:
                    pairs.append((i, j, "x", a[3], start, end))
    return pairs


def _connected(count: int, pairs: list[tuple[int, int, str, int, int, int]]) -> bool:
    parent = list(range(count))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for i, j, *_ in pairs:
        parent[root(i)] = root(j)
    return len({root(i) for i in range(count)}) == 1


def cut_corners(
    rng: np.random.Generator,
    cells: list[Cell],
    corridors: set[int],
    width: int,
    depth: int,
    count: int,
    cfg: PlanConfig,
) -> tuple[list[Cell], set[int]]:
    """Remove up to ``count`` corner cells (not corridors), keeping the rest connected."""
    for _ in range(count):
        corners = [
            i for i, c in enumerate(cells)
            if i not in corridors
            and (c[0] == 0 or c[2] == width) and (c[1] == 0 or c[3] == depth)
        ]  # fmt: skip
        for i in rng.permutation(corners):
            rest = [c for k, c in enumerate(cells) if k != i]
            if _connected(len(rest), neighbours(rest, cfg)):
                kept = [k for k in range(len(cells)) if k != i]
                corridors = {kept.index(k) for k in corridors}
                cells = rest
                break
    return cells, corridors


def choose_doors(
    rng: np.random.Generator, cells: list[Cell], corridors: set[int], cfg: PlanConfig
) -> list[Door] | None:
    """A random spanning tree of doors plus extras and openings; None if a room is cut off."""
    pairs = neighbours(cells, cfg)
    parent = list(range(len(cells)))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    doors = []
    t, g, margin = cfg.wall_thickness, cfg.grid, 0.05
    for k in rng.permutation(len(pairs)):
        i, j, axis, line, start, end = pairs[int(k)]
        joins = root(i) != root(j)
        # a corridor has a door to every room along it: that is what corridors are for
        along_corridor = (i in corridors) != (j in corridors)
        if not joins and not along_corridor and rng.random() >= cfg.extra_door_probability:
            continue
        parent[root(i)] = root(j)
        s0, s1 = start * g + t / 2 + margin, end * g - t / 2 - margin  # keep clear of corners
        opening = (
            i not in corridors
            and j not in corridors
            and (end - start) * g >= cfg.opening_min_wall
            and rng.random() < cfg.opening_probability
        )
        width = s1 - s0 if opening else min(float(rng.uniform(*cfg.door_width)), s1 - s0)
        c = float(rng.uniform(s0 + width / 2, s1 - width / 2)) if not opening else (s0 + s1) / 2
        centre = (line * g, c) if axis == "y" else (c, line * g)
        doors.append(Door(center=centre, width=width, axis=axis, rooms=(i, j)))
    if len({root(i) for i in range(len(cells))}) != 1:
        return None
    return sorted(doors, key=lambda d: (d.rooms, d.center))


def make_plan(
    rng: np.random.Generator,
    long_side: float,
    short_side: float,
    swap: bool,
    n: int,
    cfg: PlanConfig,
    max_attempts: int,
) -> Plan:
    """A floor plan with ``n`` cells (after corner cuts) of about ``long_side`` × ``short_side``.

    The footprint grows by 5 % every ``max_attempts`` failed attempts.
    """
    drawn = int(rng.integers(cfg.corner_cuts[0], cfg.corner_cuts[1] + 1))
    # Without cuts as the last resort: a house of one or two small rooms may be too small to be
    # split into extra corner cells. Trying the drawn cuts first keeps every house that could
    # take them as it was (the packaged datasets and cached grids depend on that).
    for cuts in dict.fromkeys((drawn, 0)):
        for attempt in range(10 * max_attempts):
            grow = 1.05 ** (attempt // max_attempts)
            w, d = units(long_side * grow, cfg.grid), units(short_side * grow, cfg.grid)
            width, depth = (d, w) if swap else (w, d)
            split = split_cells(rng, width, depth, n + cuts, cfg)
            if split is None:
                continue
            cells, corridors = cut_corners(rng, *split, width, depth, cuts, cfg)
            if sum(map(_area, cells)) < MIN_KEPT_SHARE * width * depth:
                break  # the cut corners would dwarf the rooms: build this house without cuts
            doors = choose_doors(rng, cells, corridors, cfg)
            if doors is not None:
                return Plan(tuple(cells), frozenset(corridors), tuple(doors), width, depth)
    raise RuntimeError(f"could not lay out a floor plan with {n} rooms")
