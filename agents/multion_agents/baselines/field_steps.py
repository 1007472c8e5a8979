"""How the explorer goes down its distance field, step by step (:class:`FieldSteps`).

One step at a time as a rule: the heading whose 0.25 m step lowers the field most
(:func:`~.navigation.choose_action`). Where none does, the caller may ask it to look two, then
three steps ahead, as two or three steps at different headings can enter a corridor whose lanes
no single step at a 30° heading reaches (val-1-on-00460); the steps found are then followed to
their end. The headings the simulator refused from where the agent stands are never tried again
before it moves.

Arriving at one position for the ``stuck_arrivals``-th time for one target, the agent is going
round in circles (val-1-on-00460 under `multion eval`'s seeds: a three-step route out and back
that retried a refused step, 40 times over). It then searches the positions its steps reach
(:class:`~.lattice_search.LatticeSearch`, as the oracle planner does), which never tries a step
twice, until it is ``search_progress`` metres further down the field, has tried every heading
of every position it knows, or has spent ``search_actions`` actions.
"""

from __future__ import annotations

import math

import numpy as np

from multion_agents.baselines.lattice_search import Key, LatticeSearch, key_of
from multion_agents.baselines.navigation import (
    Motion,
    StartFrameGrid,
    choose_action,
    interpolate,
    snap_heading,
    steps_ahead,
)
from multion_client.constants import Action


class FieldSteps:
    """The step chooser of one episode: the steps planned ahead, the headings refused here, the
    positions arrived at for the current target and the lattice search under way."""

    stuck_arrivals: int = 3
    search_progress: float = 1.0
    search_actions: int = 150

    def __init__(self, grid: StartFrameGrid, motion: Motion) -> None:
        self.grid = grid
        self.motion = motion
        self.refused_here: set[int] = set()  # headings refused where the agent stands
        self.route: list[int] = []  # headings of the steps planned ahead
        self._arrivals: dict[Key, int] = {}  # positions arrived at for the current target
        self._search: LatticeSearch | None = None
        self._search_from = math.inf  # the field value where the search started
        self._search_left = 0  # actions the search may still take
        self.searches = 0  # searches started in the episode

    def refused(self, heading: float) -> None:
        """A forward step at ``heading`` did not move the agent: drop the route, and never
        retry that heading from here."""
        index = snap_heading(heading, self.motion)[1]
        if index is not None:
            self.refused_here.add(index)
        self.route = []

    def moved(self, position: np.ndarray) -> None:
        """The agent stands somewhere new: every heading may be tried again."""
        self.refused_here = set()
        key = key_of(position)
        self._arrivals[key] = self._arrivals.get(key, 0) + 1

    def new_target(self) -> None:
        """The agent heads somewhere else: arrivals count afresh, and a search stops."""
        self._arrivals, self._search = {}, None

    def action(
        self,
        field: np.ndarray,
        passable: np.ndarray,
        position: np.ndarray,
        heading: float,
        look_ahead: int,
        search: bool = True,
    ) -> int | None:
        """The next action down ``field``: the lattice search's while one is under way (only if
        ``search``), else along the route planned ahead if there is one, else the best single
        step, else (``look_ahead`` > 1) the first of two or more steps; None at a local minimum
        (no step, nor sequence of up to ``look_ahead`` steps, goes down)."""
        if search:
            action = self._searched_action(field, position, heading)
            if action is not None:
                self.route = []
                return action
        if self.route:
            return self._follow_route(heading)
        action = choose_action(
            self.grid, field, passable, position, heading, self.motion, refused=self.refused_here
        )
        if action is None:
            action = self._start_route(field, passable, position, heading, look_ahead)
        return action

    def _searched_action(
        self, field: np.ndarray, position: np.ndarray, heading: float
    ) -> int | None:
        """The lattice search's action while the agent goes round in circles, else None."""
        grid = self.grid
        here = interpolate(grid, field, position)
        _, index = snap_heading(heading, self.motion)
        key = key_of(position)
        if index is None or not math.isfinite(here):
            return None
        if self._search is None and self._arrivals.get(key, 0) >= self.stuck_arrivals:
            self._search, self._search_from = LatticeSearch(self.motion), here
            self._search_left = self.search_actions
            self.searches += 1
        if self._search is None:
            return None
        action = None
        if here > self._search_from - self.search_progress and self._search_left > 0:
            self._search_left -= 1
            action = self._search.act(position, index, lambda p: interpolate(grid, field, p))
        if action is None:  # out of the trap, out of actions, or every known heading tried
            self._search, self._arrivals = None, {}
        return action

    def _start_route(
        self,
        field: np.ndarray,
        passable: np.ndarray,
        position: np.ndarray,
        heading: float,
        look_ahead: int,
    ) -> int | None:
        """No single step goes downhill: look two, then up to ``look_ahead`` steps ahead, and
        follow the steps found to their end."""
        for depth in range(2, look_ahead + 1):
            route = steps_ahead(
                self.grid, field, passable, position, heading, depth, self.motion,
                refused=self.refused_here,
            )  # fmt: skip
            if route:
                self.route = route
                return self._follow_route(heading)
        return None

    def _follow_route(self, heading: float) -> int:
        """Turn towards the next heading of the route, or step and drop it once facing it."""
        _, index = snap_heading(heading, self.motion)
        assert index is not None  # routes are only planned from snapped headings
        n = self.motion.headings
        turns = (self.route[0] - index) % n
        if turns == 0:
            self.route.pop(0)
            return int(Action.MOVE_FORWARD)
        return int(Action.TURN_LEFT if turns <= n // 2 else Action.TURN_RIGHT)
