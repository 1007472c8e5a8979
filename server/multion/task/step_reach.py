"""Where the agent's own moves can take it: 0.25 m forward steps and 30° turns, on the grid.

The navigable grid is connected cell to cell, but the agent does not move from cell to cell: it
steps 0.25 m along one of the 12 headings it can turn to, and a step is refused when its segment
leaves the navigable cells (:meth:`NavGrid.segment_is_navigable`, the simulator's own test). A
gap the grid passes can still be one no sequence of steps enters (a corridor mouth at 45° to
every heading, a pocket of free floor behind furniture). Episodes are sampled only where the steps
reach every goal (:func:`steps_reach_goals`).
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence

import numpy as np

from multion.config.sim import AgentConfig
from multion.sim.navgrid import NavGrid

GREEDY_EXPANSIONS = 3_000
"""Positions the best-first search expands one at a time, per goal, before it widens to whole
layers (a goal walled off from the start would otherwise be proven so one position at a time)."""


def step_headings(yaw: float, agent: AgentConfig = AgentConfig()) -> np.ndarray:
    """The headings (radians) the agent reaches by turning from ``yaw``."""
    turns = max(1, round(360.0 / agent.turn_angle_deg))
    headings: np.ndarray = yaw + np.deg2rad(agent.turn_angle_deg) * np.arange(turns)
    return headings


class StepLattice:
    """The positions found so far from a start by exact forward steps (turns are free).

    Positions closer than half a cell are merged and the first one found stands for them, so
    the search is finite; every position kept was reached by exact steps from a kept position.
    """

    def __init__(self, grid: NavGrid, xy: np.ndarray, yaw: float, agent: AgentConfig) -> None:
        headings = step_headings(yaw, agent)
        self.moves = agent.forward_step * np.stack([np.cos(headings), np.sin(headings)], axis=-1)
        samples = max(2, int(np.ceil(agent.forward_step / (grid.cell_size / 2))) + 1)
        along = np.linspace(0.0, 1.0, samples)[None, :, None]
        self.sweeps = along * self.moves[:, None, :]  # (moves, samples, 2): each step's segment
        self.grid = grid
        self.origin = np.asarray(grid.origin, dtype=np.float64)
        self.quantum = grid.cell_size / 2
        rows, cols = grid.shape
        self.seen = np.zeros((2 * rows + 2, 2 * cols + 2), dtype=bool)
        self.points = np.empty((1024, 2))
        self.count = 0
        self.expanded = np.zeros(1024, dtype=bool)
        self._add(np.asarray(xy, dtype=np.float64)[None, :2])

    def _keys(self, points: np.ndarray) -> np.ndarray:
        """The half cell of each point, as a flat index into ``seen``."""
        index = np.floor((points - self.origin) / self.quantum).astype(np.int64) + 1
        index = np.clip(index, 0, np.array(self.seen.shape[::-1]) - 1)
        return index[..., 1] * self.seen.shape[1] + index[..., 0]

    def _add(self, points: np.ndarray) -> np.ndarray:
        """Keep the first of ``points`` in each half cell not seen yet; their indices."""
        flat, first = np.unique(self._keys(points), return_index=True)
        fresh = ~self.seen.flat[flat]
        flat, points = flat[fresh], points[np.sort(first[fresh])]
        self.seen.flat[flat] = True
        end = self.count + len(points)
        if end > len(self.points):
            size = max(end, 2 * len(self.points))
            self.points = np.resize(self.points, (size, 2))
            self.expanded = np.concatenate(
                [self.expanded, np.zeros(size - len(self.expanded), bool)]
            )
        self.points[self.count : end] = points
        self.count = end
        return np.arange(end - len(points), end)

    def expand(self, indices: np.ndarray) -> np.ndarray:
        """Step from each position in every heading; the indices of the new positions found."""
        starts = self.points[indices]
        self.expanded[indices] = True
        targets = (starts[:, None, :] + self.moves[None, :, :]).reshape(-1, 2)
        fresh = np.flatnonzero(~self.seen.flat[self._keys(targets)])
        start, move = np.divmod(fresh, len(self.moves))
        sweeps = starts[start][:, None, :] + self.sweeps[move]
        return self._add(targets[fresh[self.grid.is_navigable(sweeps).all(axis=-1)]])

    def unexpanded(self) -> np.ndarray:
        return np.flatnonzero(~self.expanded[: self.count])


def steps_reach_goals(
    grid: NavGrid,
    xy: np.ndarray,
    yaw: float,
    goal_fields: Sequence[np.ndarray],
    reach: float,
    agent: AgentConfig = AgentConfig(),
    greedy_expansions: int = GREEDY_EXPANSIONS,
) -> bool:
    """True when forward steps and turns from ``(xy, yaw)`` bring the agent within ``reach``
    (geodesic, as the task measures it: each goal's distance field) of every goal.

    A best-first search over positions for each goal in turn (turning is always possible, so a
    position is a state, and each expands into its 12 forward steps): the position found so far
    that is closest to the goal along the floor is expanded first, so a reachable goal costs
    about one expansion per step of the way. After ``greedy_expansions`` it expands whole
    layers at once, which proves an unreachable goal as fast as a breadth-first search. Every
    position kept was reached by exact steps, so a True is a path the simulator follows; a False
    may (rarely) miss a path through a merged position (:class:`StepLattice`). Reaching each goal
    from the start is enough for visiting them in order: a step can be undone (turn 180°, step),
    so every position found reaches every other.
    """
    lattice = StepLattice(grid, xy, yaw, agent)
    for field in goal_fields:
        if not _reach(lattice, field, reach, greedy_expansions):
            return False
    return True


def _reach(lattice: StepLattice, field: np.ndarray, reach: float, greedy_expansions: int) -> bool:
    """Search on from ``lattice`` until a position lies within ``reach`` of ``field``'s goal."""
    grid = lattice.grid
    known = lattice.points[: lattice.count]
    distances = grid.lookup(field, known, outside=np.inf)
    if (distances <= reach).any():
        return True
    waiting = lattice.unexpanded()
    queue = _finite(distances[waiting], waiting)
    heapq.heapify(queue)
    for _ in range(greedy_expansions):
        if not queue:
            return False
        _, index = heapq.heappop(queue)
        new = lattice.expand(np.array([index]))
        if len(new):
            values = grid.lookup(field, lattice.points[new], outside=np.inf)
            if (values <= reach).any():
                return True
            for item in _finite(values, new):
                heapq.heappush(queue, item)
    frontier = lattice.unexpanded()
    while len(frontier):  # layer by layer from here
        new = lattice.expand(frontier)
        if (grid.lookup(field, lattice.points[new], outside=np.inf) <= reach).any():
            return True
        frontier = new
    return False


def _finite(distances: np.ndarray, indices: np.ndarray) -> list[tuple[float, int]]:
    """``(distance, index)`` pairs of the positions with a finite distance (the others are cut
    off from the goal on the grid)."""
    keep = np.isfinite(distances)
    return list(zip(distances[keep].tolist(), indices[keep].tolist(), strict=True))
