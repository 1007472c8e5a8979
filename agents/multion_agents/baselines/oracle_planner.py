"""``oracle-planner``: shortest paths on the oracle map (occupancy + goal objects), no learning.

It is the non-learned counterpart of the paper's OracleMap (Occ+Obj) agent: it reads the same
oracle map, at a finer resolution (0.1 m cells instead of 0.8 m, so doors and furniture gaps are
resolved) and large enough (601 cells, ±30 m) to hold a whole house (up to about 25 m long)
from the start pose.

Per episode:

1. the first oracle map is the global map in the start frame (see :mod:`.navigation`);
2. per goal, a fast-marching distance field is computed from the goal's cells;
3. each step the agent turns or steps so as to go down the field, using GPS and compass;
4. a refused forward step marks the cell it would have entered and triggers a re-plan;
5. when it stands on one position for the third time for one goal, the field is leading it round
   in circles (a gap the map's 0.1 m cells cannot resolve): it searches the positions its steps
   reach instead (:mod:`.lattice_search`) until it is 1 m further down the field;
6. FOUND once the map distance to the goal is below ``found_distance`` (1.0 m, well inside the
   1.5 m geodesic success radius, which leaves room for map discretisation); when the goal's
   cells are cut off on the map (the plan crosses occupied cells), also once they are within
   ``cut_off_found`` in a straight line, since the plan's slow crossing then overstates the way.

A 0.1 m cell is "free" when at least half of it is navigable, so a narrow gap can come out as
occupied. When the goal is unreachable through free cells, the plan may cross occupied cells,
at a tenth of the speed: the simulator then says which of them really block.
"""

from __future__ import annotations

import math
import sys
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np

from multion.config.ranges import bounded, check_fields
from multion_agents.agent import Agent, AgentError, ConfigOverrides, EnvConfigDict, Observation
from multion_agents.baselines.lattice_search import LatticeSearch, key_of
from multion_agents.baselines.navigation import (
    Motion,
    StartFrameGrid,
    cells_ahead,
    choose_action,
    distance_field,
    interpolate,
    nearest_free,
    snap_heading,
    two_step_action,
)
from multion_client.constants import MAP_FREE, MAP_OCCUPIED, MAP_UNKNOWN, Action

CELL_SIZE = 0.1
EGO_SIZE = 601
GOAL_CELLS = 1
"""Each goal is its own 0.1 m cell: the planner measures its distance to the goal's cells."""


@dataclass(frozen=True)
class OraclePlannerSettings:
    """The planner's tunables, recorded in ``metrics.json``."""

    found_distance: float = bounded(1.0, 0.0, 1.5, low_open=True)
    """Map distance to the goal that calls FOUND (inside the task's 1.5 m success radius)."""
    cut_off_found: float = bounded(0.5, 0.0, 1.5)
    """Straight-line metres to a goal cell that call FOUND when the goal is cut off on the map."""
    wall_margin: float = bounded(0.3, 0.0, 2.0)
    """Metres kept round occupied cells when planning."""
    stuck_visits: int = bounded(3, 1, sys.maxsize)
    """Visits of one position (for one goal) that start a lattice search (``sys.maxsize``:
    never, as the DAgger expert of ``learned/expert.py``)."""
    search_progress: float = bounded(1.0, 0.0, 20.0, low_open=True)
    """Metres down the field that end a lattice search."""

    def __post_init__(self) -> None:
        check_fields(self, "oracle_planner")


class OraclePlannerAgent(Agent):
    """Fast-marching planner on the oracle map, following the path with GPS + compass."""

    sensors: ClassVar[tuple[str, ...]] = ("goal", "gps", "compass", "oracle_map")
    config_overrides: ClassVar[ConfigOverrides] = {
        "maps": {"cell_size": CELL_SIZE, "ego_size": EGO_SIZE, "goal_cells": GOAL_CELLS}
    }
    motion: Motion = Motion()

    def __init__(
        self, seed: int = 0, settings: OraclePlannerSettings = OraclePlannerSettings()
    ) -> None:
        super().__init__(seed)
        self.settings = settings
        self.reset()

    def recorded_settings(self) -> dict[str, Any]:
        return asdict(self.settings)

    def configure(self, config: EnvConfigDict) -> None:
        """Checks the oracle map's geometry; takes the action magnitudes (``agent``)."""
        super().configure(config)
        maps = config["maps"]
        wanted = self.config_overrides["maps"]
        wrong = {k: maps.get(k) for k, v in wanted.items() if maps.get(k) != v}
        if wrong:
            have = ", ".join(f"maps.{k}={v}" for k, v in wrong.items())
            need = ", ".join(f"maps.{k}={v}" for k, v in wanted.items())
            raise AgentError(
                f"oracle-planner reads its oracle map as {need}, but this environment has "
                f"{have}: leave the agent's maps settings as they are"
            )
        try:
            self.motion = Motion.from_config(config["agent"])
        except ValueError as error:
            raise AgentError(f"oracle-planner: {error}") from None
        self.reset()

    def reset(self) -> None:
        self._grid: StartFrameGrid | None = None
        self._layers = np.zeros((0, 0, 2), dtype=np.uint8)  # the map, in the start frame
        self._refused = np.zeros((0, 0), dtype=bool)  # cells a forward step was refused into
        self._stood = np.zeros((0, 0), dtype=bool)  # cells the agent has stood in
        self._moves = np.zeros((0, 0), dtype=bool)  # cells the current plan may cross
        self._cut_off = False  # the goal is unreachable through free cells: the plan crawls
        self._field: np.ndarray | None = None
        self._goal: int | None = None
        self._last_position: np.ndarray | None = None
        self._last_action: int | None = None
        self._visits: dict[tuple[int, int], int] = {}
        self._search: LatticeSearch | None = None
        self._search_from = math.inf  # the field value where the search started
        self.replans = 0
        self.searches = 0

    def act(self, observation: Observation) -> int:
        position = np.asarray(observation["gps"], dtype=np.float64)
        heading = float(observation["compass"][0])
        ego = observation["oracle_map"]
        if self._grid is None:
            self._start_map(ego)
        assert self._grid is not None
        refused = (
            self._last_action == Action.MOVE_FORWARD
            and self._last_position is not None
            and np.allclose(position, self._last_position, atol=1e-4)
        )
        if refused:
            ahead = cells_ahead(self._grid, position, heading, self.motion)
            self._refused[ahead] = True
            self._field = None
            self.replans += 1
        row, col = (int(v) for v in self._grid.to_cell(position))
        if not self._stood[row, col]:
            self._stood[row, col] = True
            if not self._moves[row, col]:
                self._field = None  # the map rounded this cell to occupied: re-plan from here
        goal = int(observation["goal"])
        if goal != self._goal:
            self._goal, self._field = goal, None
            self._visits, self._search = {}, None
        if self._field is None:
            self._field = self._plan(goal, ego, position, heading)
        action = self._searched_action(position, heading)
        if action is None:
            action = self._next_action(position, heading, refused)
        self._last_position, self._last_action = position, action
        return action

    def took(self, action: int) -> None:
        """The action the environment took after the last ``act``, when another agent is in
        control (imitation learning labels a learner's steps with this agent's actions)."""
        self._last_action = action

    # ------------------------------------------------------------------ internals
    def _start_map(self, ego: np.ndarray) -> None:
        size = ego.shape[0]
        maps = self.config_overrides["maps"]
        cell = float(maps["cell_size"])
        if size != maps["ego_size"]:
            # a smaller map (a track's default 50 cells of 0.8 m) read as 0.1 m cells would be
            # wrong everywhere, and the agent would walk off it
            raise AgentError(
                f"oracle-planner needs an oracle map of {maps['ego_size']} cells of {cell} m "
                f"(maps.ego_size={maps['ego_size']}, maps.cell_size={cell}), got {size} cells: "
                "ask for its maps (multion submit and eval do) or use a track that allows them"
            )
        self._grid = StartFrameGrid(size, cell)
        self._layers = ego.copy()
        self._refused = np.zeros((size, size), dtype=bool)
        self._stood = np.zeros((size, size), dtype=bool)
        self._moves = np.zeros((size, size), dtype=bool)

    def _plan(self, goal: int, ego: np.ndarray, position: np.ndarray, heading: float) -> np.ndarray:
        """Distance field to the goal's cells, or to the map's frontier while they are unseen."""
        assert self._grid is not None
        sources = self._layers[..., 1] == goal + 1
        if not sources.any():
            # the goal lies outside the first crop: add what the agent sees now
            self._paste(ego, position, heading)
            sources = self._layers[..., 1] == goal + 1
        passable = ((self._layers[..., 0] == MAP_FREE) | self._stood) & ~self._refused
        if not sources.any():
            sources = self._frontier(passable)
        cell = self._grid.cell_size
        self._moves, self._cut_off = passable, False
        field = distance_field(
            passable, nearest_free(sources, passable, 5), cell, self.settings.wall_margin
        )
        if np.isfinite(interpolate(self._grid, field, position)):
            return field
        self._cut_off = True
        # unreachable through free cells: also cross occupied ones, slowly
        relaxed = passable | ((self._layers[..., 0] == MAP_OCCUPIED) & ~self._refused)
        self._moves = relaxed
        targets = nearest_free(sources, relaxed, 5)
        return distance_field(
            relaxed, targets, cell, self.settings.wall_margin, crawl=relaxed & ~passable
        )

    def _searched_action(self, position: np.ndarray, heading: float) -> int | None:
        """The lattice search's action while the field goes round in circles, else None."""
        assert self._grid is not None and self._field is not None
        grid, field = self._grid, self._field
        here = float(interpolate(grid, field, position))
        _, index = snap_heading(heading, self.motion)
        if self._at_goal(position, here) or index is None:
            return None
        visits = self._visits[key_of(position)] = self._visits.get(key_of(position), 0) + 1
        if self._search is None and visits >= self.settings.stuck_visits:
            self._search, self._search_from = LatticeSearch(self.motion), here
            self.searches += 1
        if self._search is None:
            return None
        if here <= self._search_from - self.settings.search_progress:
            self._search, self._visits = None, {}  # out of the trap
            return None
        action = self._search.act(position, index, lambda p: float(interpolate(grid, field, p)))
        if action is None:
            self._search = None  # every known heading tried: back to the field
        return action

    def _next_action(self, position: np.ndarray, heading: float, refused: bool) -> int:
        assert self._grid is not None and self._field is not None
        if self._at_goal(position, interpolate(self._grid, self._field, position)):
            return int(Action.FOUND)
        action = choose_action(self._grid, self._field, self._moves, position, heading, self.motion)
        if action is None:
            action = two_step_action(
                self._grid, self._field, self._moves, position, heading, self.motion
            )
        if action is None:
            # no step goes downhill through the cells the plan may cross: probe straight ahead,
            # and turn after a refused probe; the simulator, not the map, has the last word
            action = int(Action.TURN_LEFT if refused else Action.MOVE_FORWARD)
        return action

    def _at_goal(self, position: np.ndarray, here: float) -> bool:
        """Time for FOUND: the goal is on the map and the plan says it is near."""
        assert self._goal is not None  # act() sets it before planning
        if not (self._layers[..., 1] == self._goal + 1).any():
            return False
        return here <= self.settings.found_distance or self._near_cut_off_goal(position)

    def _near_cut_off_goal(self, position: np.ndarray) -> bool:
        """A goal whose cells the map cuts off (val-2-on-00650: the plan's crawl through occupied
        cells never came under 1.0 m while the agent stood 0.45 m from the goal) is near when
        one of its cells is within ``cut_off_found`` in a straight line."""
        if not self._cut_off:
            return False
        assert self._grid is not None and self._goal is not None
        rows, cols = np.nonzero(self._layers[..., 1] == self._goal + 1)
        gaps = self._grid.to_xy(rows, cols) - position
        return (
            bool(len(gaps))
            and float(np.hypot(gaps[..., 0], gaps[..., 1]).min()) <= self.settings.cut_off_found
        )

    def _frontier(self, passable: np.ndarray) -> np.ndarray:
        unknown = self._layers[..., 0] == MAP_UNKNOWN
        near_unknown = np.zeros_like(unknown)
        near_unknown[1:] |= unknown[:-1]
        near_unknown[:-1] |= unknown[1:]
        near_unknown[:, 1:] |= unknown[:, :-1]
        near_unknown[:, :-1] |= unknown[:, 1:]
        frontier: np.ndarray = passable & near_unknown
        return frontier

    def _paste(self, ego: np.ndarray, position: np.ndarray, heading: float) -> None:
        """Write the known cells of an egocentric map taken at ``position``/``heading``."""
        assert self._grid is not None
        grid, half = self._grid, ego.shape[0] // 2
        rows, cols = np.nonzero(ego[..., 0] != MAP_UNKNOWN)
        forward = (half - rows) * grid.cell_size
        left = (half - cols) * grid.cell_size
        c, s = math.cos(heading), math.sin(heading)
        points = np.stack(
            [position[0] + c * forward - s * left, position[1] + s * forward + c * left], axis=-1
        )
        r, k = grid.to_cell(points)
        ok = (r >= 0) & (r < grid.size) & (k >= 0) & (k < grid.size)
        self._layers[r[ok], k[ok]] = ego[rows[ok], cols[ok]]
