"""Episode measures (SPEC §3): each a small class with ``reset`` / ``update`` / ``value``.

Measures read an :class:`EpisodeState` that the task keeps up to date, and may read measures they
declare in ``depends_on`` (SPL depends on Success and PathLength); :class:`Measures` updates them
in dependency order.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from multion.config.episode import Episode
from multion.task.sensors import start_frame

MetricValue = float | int | str | None | list[float] | list[bool]


@dataclass
class EpisodeState:
    """What happened so far in the current episode, as the task records it."""

    episode: Episode
    optimal_distances: tuple[float, ...]
    """Geodesic d(start, g1), d(g1, g2), … measured at reset."""
    position: np.ndarray
    step: int = 0
    collided: bool = False
    found_correct: bool = False
    found_wrong: bool = False
    goals_found: int = 0
    wrong_founds: int = 0
    distractor_founds: int = 0
    """Wrong FOUNDs called within the success distance of a distractor."""
    distance_to_goal: float = 0.0
    first_seen_step: list[int | None] = field(default_factory=list)
    current_since_step: list[int | None] = field(default_factory=list)
    end_reason: str | None = None


class Measure(ABC):
    """One metric. ``name`` is its key in the metrics dict."""

    name: ClassVar[str]
    depends_on: ClassVar[tuple[str, ...]] = ()

    @abstractmethod
    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None: ...

    @abstractmethod
    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None: ...

    @property
    @abstractmethod
    def value(self) -> MetricValue: ...


def number(measures: Mapping[str, Measure], name: str) -> float:
    """The value of a declared dependency that is a number (a ``TypeError`` names it if not)."""
    value = measures[name].value
    if not isinstance(value, int | float):
        raise TypeError(f"measure {name!r} is {type(value).__name__}, not a number")
    return float(value)


def series(measures: Mapping[str, Measure], name: str) -> list[float]:
    """The value of a declared dependency that is a list of numbers."""
    value = measures[name].value
    if not isinstance(value, list) or not all(isinstance(v, int | float) for v in value):
        raise TypeError(f"measure {name!r} is {type(value).__name__}, not a list of numbers")
    return [float(v) for v in value]


class Steps(Measure):
    name = "steps"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = 0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = state.step

    @property
    def value(self) -> int:
        return self._value


class Collisions(Measure):
    name = "collisions"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = 0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value += int(state.collided)

    @property
    def value(self) -> int:
        return self._value


class PathLength(Measure):
    """p: metres actually walked (turns and FOUND add nothing)."""

    name = "path_length"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = 0.0
        self._previous = state.position.copy()

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value += float(np.hypot(*(state.position - self._previous)))
        self._previous = state.position.copy()

    @property
    def value(self) -> float:
        return self._value


class DistanceToGoal(Measure):
    """Geodesic distance to the current goal (0 once every goal is found)."""

    name = "distance_to_goal"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = state.distance_to_goal

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = state.distance_to_goal

    @property
    def value(self) -> float:
        return self._value


class ClosestToGoal(Measure):
    """The shortest geodesic distance to the current goal since it became current (0 once
    every goal is found). Below ``task.success_distance`` in an episode that did not find that
    goal: the agent stood within reach and did not call FOUND there (beyond the paper; issue
    51's measurement of where the agents that must see the goal lose it)."""

    name = "closest_to_goal"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._goal = state.goals_found
        self._value = state.distance_to_goal

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        if state.goals_found != self._goal:  # a new current goal: start again from here
            self._goal = state.goals_found
            self._value = state.distance_to_goal
        else:
            self._value = min(self._value, state.distance_to_goal)

    @property
    def value(self) -> float:
        return self._value


class GoalsFound(Measure):
    name = "goals_found"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = 0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = state.goals_found

    @property
    def value(self) -> int:
        return self._value


class WrongFounds(Measure):
    name = "wrong_founds"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = 0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = state.wrong_founds

    @property
    def value(self) -> int:
        return self._value


class DistractorFounds(Measure):
    """Wrong FOUNDs called at a distractor (within the success distance of one)."""

    name = "distractor_founds"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = 0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = state.distractor_founds

    @property
    def value(self) -> int:
        return self._value


class Progress(Measure):
    """Fraction of the goals found."""

    name = "progress"
    depends_on = ("goals_found",)

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._m = state.episode.num_goals
        self._value = 0.0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = number(measures, "goals_found") / self._m

    @property
    def value(self) -> float:
        return self._value


class Success(Measure):
    """1 when all goals were found, in order, within the step limit."""

    name = "success"
    depends_on = ("goals_found",)

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._m = state.episode.num_goals
        self._value = 0.0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = float(measures["goals_found"].value == self._m)

    @property
    def value(self) -> float:
        return self._value


class SPL(Measure):
    """s · d / max(p, d) with d the geodesic length start → g1 → … → gm."""

    name = "spl"
    depends_on = ("success", "path_length")

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._d = float(sum(state.optimal_distances))
        self._value = 0.0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        s = number(measures, "success")
        p = number(measures, "path_length")
        self._value = s * self._d / max(p, self._d)

    @property
    def value(self) -> float:
        return self._value


class PPL(Measure):
    """Paper's PPL: progress · d̄ / max(p, d̄), d̄ through the goals found, p the whole path."""

    name = "ppl"
    depends_on = ("progress", "goals_found", "path_length")

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._optimal = state.optimal_distances
        self._value = 0.0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        found = int(number(measures, "goals_found"))
        if found == 0:
            self._value = 0.0
            return
        d_bar = float(sum(self._optimal[:found]))
        p = number(measures, "path_length")
        self._value = number(measures, "progress") * d_bar / max(p, d_bar)

    @property
    def value(self) -> float:
        return self._value


class PathLengthAtFound(Measure):
    """Path length walked at each correct FOUND, in order."""

    name = "path_length_at_found"
    depends_on = ("path_length",)

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value: list[float] = []

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        if state.found_correct:
            self._value.append(number(measures, "path_length"))

    @property
    def value(self) -> list[float]:
        return list(self._value)


class ReferencePPL(Measure):
    """The reference code's PPL variant: p is the path length at the last correct FOUND."""

    name = "ppl_reference"
    depends_on = ("progress", "path_length_at_found")

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._optimal = state.optimal_distances
        self._value = 0.0

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        at_found = series(measures, "path_length_at_found")
        if not at_found:
            self._value = 0.0
            return
        d_bar = float(sum(self._optimal[: len(at_found)]))
        self._value = number(measures, "progress") * d_bar / max(at_found[-1], d_bar)

    @property
    def value(self) -> float:
        return self._value


class SeenBeforeCurrent(Measure):
    """Per goal k ≥ 2: was it seen before goal k-1 was found (the supplement's seen / not-seen)?"""

    name = "seen_before_current"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._state = state

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._state = state

    @property
    def value(self) -> list[bool]:
        s = self._state
        out = []
        for k in range(1, s.episode.num_goals):
            seen, since = s.first_seen_step[k], s.current_since_step[k]
            # a goal never made current was "seen before" if it was seen at all
            out.append(seen is not None and (since is None or seen < since))
        return out


class CurrentGoalSeen(Measure):
    """Whether the goal the episode is on (the current goal; the last one once every goal is
    found) has been in view: in the camera's field of view, within ``maps.view_distance``, with
    a clear line on the navigation grid (the test :class:`SeenBeforeCurrent` uses). An episode
    lost with it saw its goal and did not get there; one lost without it never saw the goal
    (beyond the paper; issue 51's split of the search failures)."""

    name = "current_goal_seen"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._state = state

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._state = state

    @property
    def value(self) -> bool:
        s = self._state
        return s.first_seen_step[min(s.goals_found, s.episode.num_goals - 1)] is not None


SCORING_SENSORS = ("goal",)
"""What an environment that replays stored actions only to score them observes: metrics do not
depend on what is rendered, so such a replay renders nothing."""


def metrics_as_stored(metrics: Mapping[str, Any], stored: Mapping[str, Any]) -> dict[str, Any]:
    """``metrics`` without the measures that ``stored`` lacks: a measure added to the task
    after a run was stored (``cells_visited``) is no difference in its replay."""
    return {key: value for key, value in metrics.items() if key in stored}


def seen_split(metrics: Iterable[Mapping[str, Any]], goal: int) -> tuple[list[float], list[float]]:
    """1.0 / 0.0 (goal ``goal`` found or not) for the episodes in which goal ``goal - 1`` was
    found, split into those where ``goal`` was seen before that (by :class:`SeenBeforeCurrent`)
    and those where it was not: the supplement's seen / not-seen analysis, from each episode's
    ``info["metrics"]``."""
    seen: list[float] = []
    unseen: list[float] = []
    for m in metrics:
        found = int(m.get("goals_found", 0))
        flags = m.get("seen_before_current") or []
        if found < goal - 1 or len(flags) < goal - 1:
            continue  # the agent never got to look for this goal
        (seen if flags[goal - 2] else unseen).append(float(found >= goal))
    return seen, unseen


VISIT_CELL_SIZE = 2.5
"""Side of the grid :class:`CellsVisited` counts, metres: Ye et al.'s coverage grid
(joel99/objectnav ``configs/tasks/objectnav_mp3d_full.yaml`` l. 52-58, ``GRID_DELTA`` 2.5)."""


def visit_cell(ahead: float, left: float) -> tuple[int, int]:
    """The :data:`VISIT_CELL_SIZE` cell holding a point ``ahead``, ``left`` metres of the
    episode's start in its start frame (the ``gps`` sensor's frame); the start lies at a cell's
    centre."""
    return (
        math.floor(ahead / VISIT_CELL_SIZE + 0.5),
        math.floor(left / VISIT_CELL_SIZE + 0.5),
    )


class CellsVisited(Measure):
    """How many cells of a 2.5 m grid in the start frame the agent has stood in, the start's
    included: how much ground its search covered (beyond the paper; issue 51's measurement of
    agents that search without a map)."""

    name = "cells_visited"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._start = np.asarray(state.episode.start_position[:2], dtype=np.float64)
        self._cells: set[tuple[int, int]] = set()
        self.update(state, measures)

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        position = np.asarray(state.position[:2], dtype=np.float64)
        self._cells.add(visit_cell(*start_frame(position, self._start, state.episode.start_yaw)))

    @property
    def value(self) -> int:
        return len(self._cells)


class EndReason(Measure):
    """``success``, ``wrong_found``, ``max_steps``, or None while the episode runs."""

    name = "end_reason"

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value: str | None = None

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        self._value = state.end_reason

    @property
    def value(self) -> str | None:
        return self._value


DEFAULT_MEASURES: tuple[type[Measure], ...] = (
    Steps,
    Collisions,
    PathLength,
    DistanceToGoal,
    ClosestToGoal,
    GoalsFound,
    WrongFounds,
    DistractorFounds,
    Progress,
    Success,
    SPL,
    PPL,
    PathLengthAtFound,
    ReferencePPL,
    SeenBeforeCurrent,
    CurrentGoalSeen,
    CellsVisited,
    EndReason,
)


class Measures:
    """A set of measures updated in dependency order."""

    def __init__(self, kinds: tuple[type[Measure], ...] = DEFAULT_MEASURES) -> None:
        by_name = {kind.name: kind for kind in kinds}
        order: list[str] = []

        def visit(name: str, trail: tuple[str, ...]) -> None:
            if name in order:
                return
            if name in trail:
                raise ValueError(f"measure dependency cycle: {' -> '.join(trail + (name,))}")
            if name not in by_name:
                raise ValueError(f"measure {trail[-1]!r} depends on unknown measure {name!r}")
            for dep in by_name[name].depends_on:
                visit(dep, trail + (name,))
            order.append(name)

        for kind in kinds:
            visit(kind.name, ())
        self._measures: dict[str, Measure] = {name: by_name[name]() for name in order}

    def reset(self, state: EpisodeState) -> None:
        for measure in self._measures.values():
            measure.reset(state, self._measures)

    def update(self, state: EpisodeState) -> None:
        for measure in self._measures.values():
            measure.update(state, self._measures)

    def values(self) -> dict[str, MetricValue]:
        return {name: measure.value for name, measure in self._measures.items()}
