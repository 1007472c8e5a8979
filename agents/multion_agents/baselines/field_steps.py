"""How the explorer goes down its distance field, step by step (:class:`FieldSteps`).

One step at a time as a rule: the heading whose 0.25 m step lowers the field most
(:func:`~.navigation.choose_action`). Where none does, the caller may ask it to look two, then
three steps ahead, as two or three steps at different headings can enter a corridor whose lanes
no single step at a 30° heading reaches (val-1-on-00460); the steps found are then followed to
their end. The headings the simulator refused from where the agent stands are never tried again
before it moves.
"""

from __future__ import annotations

import numpy as np

from multion_agents.baselines.navigation import (
    Motion,
    StartFrameGrid,
    choose_action,
    snap_heading,
    steps_ahead,
)
from multion_client.constants import Action


class FieldSteps:
    """The step chooser of one episode: the steps planned ahead and the headings refused here."""

    def __init__(self, grid: StartFrameGrid, motion: Motion) -> None:
        self.grid = grid
        self.motion = motion
        self.refused_here: set[int] = set()  # headings refused where the agent stands
        self.route: list[int] = []  # headings of the steps planned ahead

    def refused(self, heading: float) -> None:
        """A forward step at ``heading`` did not move the agent: drop the route, and never
        retry that heading from here."""
        index = snap_heading(heading, self.motion)[1]
        if index is not None:
            self.refused_here.add(index)
        self.route = []

    def moved(self) -> None:
        """The agent stands somewhere new: every heading may be tried again."""
        self.refused_here = set()

    def action(
        self,
        field: np.ndarray,
        passable: np.ndarray,
        position: np.ndarray,
        heading: float,
        look_ahead: int,
    ) -> int | None:
        """The next action down ``field``: along the route planned ahead if there is one, else
        the best single step, else (``look_ahead`` > 1) the first of two or more steps; None at
        a local minimum (no step, nor sequence of up to ``look_ahead`` steps, goes down)."""
        if self.route:
            return self._follow_route(heading)
        action = choose_action(
            self.grid, field, passable, position, heading, self.motion, refused=self.refused_here
        )
        if action is None:
            action = self._start_route(field, passable, position, heading, look_ahead)
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
