"""A way out when following the map's distance field goes round in circles: search the positions
the agent's own steps reach, with the simulator as the judge of every step.

A map of 0.1 m cells cannot say which of the 12 step headings pass a gap one fine cell wide: the
field may lead into a pocket that steps cannot leave but backwards, and back into it once out.
:class:`LatticeSearch` remembers every (position, heading) it tried and where each successful
step led, tries the untried headings of the position it stands on in order of the field value
where they would end, and when none is left walks back along known steps to the known position
whose best untried heading ends lowest. Positions are GPS readings (exact: a step adds the same
vector each time), headings the 12 indices of :func:`~.navigation.snap_heading`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import numpy as np

from multion_agents.baselines.navigation import Motion
from multion_client.constants import Action

Key = tuple[int, int]
Edge = tuple[Key, int]
TURN_COST = 0.01
"""Metres of field value a turn is worth when ranking headings (a tie-breaker)."""
BACKTRACK_COST = 0.25
"""Metres of field value per known step walked back to reach an untried heading."""


def key_of(position: np.ndarray) -> Key:
    """A position to the centimetre (steps of 0.25 m never land within 1 cm of each other)."""
    return (round(float(position[0]) * 100), round(float(position[1]) * 100))


class LatticeSearch:
    """Online search over step positions; :meth:`act` gives the next action, or None when every
    heading of every known position has been tried."""

    def __init__(self, motion: Motion = Motion()) -> None:
        self.motion = motion
        self.tried: dict[Key, set[int]] = {}
        self.steps: dict[Edge, Key] = {}
        self._leaving: dict[Key, dict[int, Key]] = {}
        """The known steps by start: heading → end (``steps`` indexed for the route search)."""
        self.points: dict[Key, np.ndarray] = {}
        self._pending: Edge | None = None
        self._route: deque[Edge] = deque()

    def act(
        self, position: np.ndarray, heading: int, value: Callable[[np.ndarray], float]
    ) -> int | None:
        here = key_of(position)
        self.points[here] = np.asarray(position, dtype=np.float64).copy()
        self.tried.setdefault(here, set())
        if self._pending is not None:
            start, direction = self._pending
            self._pending = None
            if here != start:
                self.steps[(start, direction)] = here
                self._leaving.setdefault(start, {})[direction] = here
        if self._route and self._route[0][0] != here:
            self._route.clear()  # not where the route expected: choose again
        if not self._route:
            target = self._best_heading(here, value)
            if target is None:
                self._route = self._route_to_untried(here, value)
                if not self._route:
                    return None
            else:
                self._route.append((here, target))
        _, direction = self._route[0]
        turns = (direction - heading) % self.motion.headings
        if turns == 0:
            self._route.popleft()
            self.tried[here].add(direction)
            self._pending = (here, direction)
            return int(Action.MOVE_FORWARD)
        return int(Action.TURN_LEFT if turns <= self.motion.headings // 2 else Action.TURN_RIGHT)

    def _end(self, key: Key, direction: int) -> np.ndarray:
        angle = direction * self.motion.turn_angle
        step = self.motion.forward_step * np.array([math.cos(angle), math.sin(angle)])
        return self.points[key] + step

    def _ranked(self, key: Key, value: Callable[[np.ndarray], float]) -> list[tuple[float, int]]:
        """Untried headings of ``key`` with a finite value where they end, best first."""
        options = []
        for direction in range(self.motion.headings):
            if direction in self.tried[key]:
                continue
            end_value = value(self._end(key, direction))
            if math.isfinite(end_value):
                options.append((end_value, direction))
        return sorted(options)

    def _best_heading(self, key: Key, value: Callable[[np.ndarray], float]) -> int | None:
        ranked = self._ranked(key, value)
        return ranked[0][1] if ranked else None

    def _route_to_untried(self, here: Key, value: Callable[[np.ndarray], float]) -> deque[Edge]:
        """Known steps from ``here`` to the position whose best untried heading ends lowest
        (counting the walk back), followed by that heading; empty if none is left."""
        came_from: dict[Key, Edge | None] = {here: None}
        depth = {here: 0}
        queue = deque([here])
        best: tuple[float, Key, int] | None = None
        while queue:
            key = queue.popleft()
            ranked = self._ranked(key, value)
            if ranked:
                cost = ranked[0][0] + BACKTRACK_COST * depth[key]
                if best is None or cost < best[0]:
                    best = (cost, key, ranked[0][1])
            for direction, end in self._leaving.get(key, {}).items():
                if end not in came_from:
                    came_from[end] = (key, direction)
                    depth[end] = depth[key] + 1
                    queue.append(end)
        if best is None:
            return deque()
        _, key, direction = best
        route: deque[Edge] = deque([(key, direction)])
        while came_from[key] is not None:
            edge = came_from[key]
            assert edge is not None
            route.appendleft(edge)
            key = edge[0]
        return route
