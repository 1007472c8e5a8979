"""Where the agent's own moves can take it: 0.25 m forward steps and 30° turns, on the grid.

The navigable grid is connected cell to cell, but the agent does not move from cell to cell: it
steps 0.25 m along one of the 12 headings it can turn to, and a step is refused when its segment
leaves the navigable cells (:meth:`NavGrid.segment_is_navigable`, the simulator's own test). A
gap the grid passes can still be one no sequence of such steps enters (a corridor mouth at 45° to
every heading, a pocket of free floor behind furniture). Episodes are sampled only where the steps
reach every goal (:func:`steps_reach_goals`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from multion.sim.navgrid import NavGrid
from multion.sim.simulator import AgentConfig


def step_headings(yaw: float, agent: AgentConfig = AgentConfig()) -> np.ndarray:
    """The headings (radians) the agent reaches by turning from ``yaw``."""
    turns = max(1, round(360.0 / agent.turn_angle_deg))
    return yaw + np.deg2rad(agent.turn_angle_deg) * np.arange(turns)


def steps_reach_goals(
    grid: NavGrid,
    xy: np.ndarray,
    yaw: float,
    goal_fields: Sequence[np.ndarray],
    reach: float,
    agent: AgentConfig = AgentConfig(),
) -> bool:
    """True when forward steps and turns from ``(xy, yaw)`` bring the agent within ``reach``
    (geodesic, as the task measures it: each goal's distance field) of every goal.

    A breadth-first search over positions: turning is always possible, so a position is a state,
    and each expands into its 12 forward steps. Positions closer than half a cell are merged and
    the first one found stands for them; every position kept was reached by exact steps from the
    start, so a True is a path the simulator follows, and a False may (rarely) miss a path through
    a merged position. Reaching each goal from the start is enough for visiting them in order:
    a step can be undone (turn 180°, step), so every position found reaches every other.
    """
    headings = step_headings(yaw, agent)
    moves = agent.forward_step * np.stack([np.cos(headings), np.sin(headings)], axis=-1)
    samples = max(2, int(np.ceil(agent.forward_step / (grid.cell_size / 2))) + 1)
    along = np.linspace(0.0, 1.0, samples)[None, :, None]
    quantum = grid.cell_size / 2
    rows, cols = grid.shape
    seen = np.zeros((2 * rows + 2, 2 * cols + 2), dtype=bool)
    pending = list(range(len(goal_fields)))

    origin = np.asarray(grid.origin)

    def keys(points: np.ndarray) -> np.ndarray:
        """The half cell of each point, as a flat index into ``seen``."""
        index = np.floor((points - origin) / quantum).astype(np.int64) + 1
        index = np.clip(index, 0, np.array(seen.shape[::-1]) - 1)
        return index[..., 1] * seen.shape[1] + index[..., 0]

    frontier = np.asarray(xy, dtype=np.float64)[None, :2]
    seen.flat[keys(frontier)] = True
    while len(frontier):
        pending = [
            g
            for g in pending
            if not (grid.lookup(goal_fields[g], frontier, outside=np.inf) <= reach).any()
        ]
        if not pending:
            return True
        targets = (frontier[:, None, :] + moves[None, :, :]).reshape(-1, 2)
        starts = np.repeat(frontier, len(moves), axis=0)
        fresh = ~seen.flat[keys(targets)]
        targets, starts = targets[fresh], starts[fresh]
        segments = starts[:, None, :] + along * (targets - starts)[:, None, :]
        targets = targets[grid.is_navigable(segments).all(axis=-1)]
        flat, first = np.unique(keys(targets), return_index=True)
        seen.flat[flat] = True
        frontier = targets[first]
    return False
