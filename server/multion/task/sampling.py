"""Episodes on a scene's navigable grid: the online sampler (start, goals and distractors, SPEC
§5) and the check that a given episode stands on the grid (:func:`check_on_grid`). It marches distance fields, so it needs the simulator's grid; the
files it fills are read and written by the light :mod:`multion.config.datasets`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np

from multion.config.episode import Episode, Goal
from multion.config.sim import AgentConfig
from multion.config.task import EpisodeConstraints
from multion.sim.geodesic import FieldCache, distance_field
from multion.sim.navgrid import NavGrid
from multion.task.errors import BadEpisodeError
from multion.task.step_reach import step_headings, steps_reach_goals
from multion_client.constants import NUM_CATEGORIES


def sample_episode(
    grid: NavGrid,
    scene_id: str,
    num_goals: int,
    rng: np.random.Generator,
    episode_id: str,
    constraints: EpisodeConstraints = EpisodeConstraints(),
    goal_radius: float = 0.05,
    num_distractors: int = 0,
    fields: FieldCache | None = None,
) -> Episode | None:
    """Sample one episode in a scene, or None when ``max_tries`` starts all fail.

    Start and goals are navigable cell centres of the (single-floor, connected) grid; each next
    point is drawn among cells at geodesic 2–20 m from the previous one, at least
    ``min_goal_separation`` from earlier goals; categories are drawn without replacement.
    ``num_distractors`` more cylinders then take categories that are not the goals' and navigable
    cells at least ``min_distractor_separation`` from every goal (and ``min_goal_separation`` from
    each other). With no distractors the random stream is the same as before they existed.
    ``fields``, when given, keeps the goals' distance fields for the episode's reset (the
    caller's env reads them there).
    """
    if not 0 <= num_distractors <= NUM_CATEGORIES - num_goals:
        raise ValueError(
            f"num_distractors must be in 0..{NUM_CATEGORIES - num_goals} for {num_goals} goals, "
            f"got {num_distractors}"
        )
    fields = fields if fields is not None else FieldCache()
    rows, cols = np.nonzero(grid.navigable)
    cells = grid.cell_to_world(rows, cols)
    z = grid.floor_z
    for _ in range(constraints.max_tries):
        start = cells[rng.integers(len(cells))]
        points = [start]
        measured: list[float] = []
        goal_fields: list[np.ndarray] = []
        # Each leg's candidates come from the previous point's field: the start's (a point), then
        # each goal's, made with its footprint as the env makes it, which also gives the leg's
        # distance exactly as the env measures it. m + 1 fast marchings per episode.
        field = distance_field(grid, start, 0.0)
        for _goal in range(num_goals):
            near = field[rows, cols]
            ok = (near >= constraints.min_geodesic) & (near <= constraints.max_geodesic)
            for earlier in points[1:]:
                ok &= np.hypot(*(cells - earlier).T) >= constraints.min_goal_separation
            candidates = np.flatnonzero(ok)
            if len(candidates) == 0:
                break
            pick = candidates[rng.integers(len(candidates))]
            goal_xy = np.round(cells[pick], 4)
            field = fields.get(grid, goal_xy, goal_radius)
            goal_fields.append(field)
            measured.append(float(grid.lookup(field, points[-1], outside=np.inf)))
            points.append(goal_xy)
        if len(points) != num_goals + 1:
            continue
        categories = rng.choice(NUM_CATEGORIES, size=num_goals, replace=False)
        goals = tuple(
            Goal(category=int(c), position=(float(p[0]), float(p[1]), z))
            for c, p in zip(categories, points[1:], strict=True)
        )
        if not all(constraints.min_geodesic <= d <= constraints.max_geodesic for d in measured):
            continue  # the footprint distance can differ from the cell distance by a few cm
        episode = finish_episode(
            rng, grid, episode_id, scene_id, start, goals, measured,
            functools.partial(list, goal_fields), constraints, num_distractors, lambda: cells,
        )  # fmt: skip
        if episode is not None:
            return episode
    return None


def finish_episode(
    rng: np.random.Generator,
    grid: NavGrid,
    episode_id: str,
    scene_id: str,
    start: np.ndarray,
    goals: tuple[Goal, ...],
    measured: Sequence[float],
    goal_fields: Callable[[], Sequence[np.ndarray]],
    constraints: EpisodeConstraints,
    num_distractors: int,
    cells: Callable[[], np.ndarray],
) -> Episode | None:
    """The end both samplers share (this one and :mod:`.goal_sites`), drawing from ``rng`` in
    the same order: distractors among ``cells()``, the start's heading; then the start must be
    able to step and the agent's steps must reach every goal (``goal_fields()``, the goals'
    fields, is called only then). None where a draw or a check fails."""
    distractors = (
        sample_distractors(rng, cells(), goals, num_distractors, constraints, grid.floor_z)
        if num_distractors
        else ()
    )
    if distractors is None:
        return None
    start_xy = (round(float(start[0]), 4), round(float(start[1]), 4))
    start_yaw = round(float(rng.uniform(-np.pi, np.pi)), 6)
    if constraints.mobile_start and not can_step(grid, np.asarray(start_xy), start_yaw):
        return None
    if constraints.step_paths and not steps_reach_goals(
        grid, np.asarray(start_xy), start_yaw, goal_fields(), constraints.reach
    ):
        return None
    return Episode(
        episode_id=episode_id,
        scene_id=scene_id,
        start_position=(*start_xy, grid.floor_z),
        start_yaw=start_yaw,
        goals=goals,
        geodesic_distances=tuple(measured),
        distractors=distractors,
    )


def can_step(grid: NavGrid, xy: np.ndarray, yaw: float, agent: AgentConfig = AgentConfig()) -> bool:
    """True if a MOVE_FORWARD from ``xy`` succeeds in at least one of the headings the agent
    reaches by turning from ``yaw`` (the simulator's own test: the segment on the grid)."""
    for heading in step_headings(yaw, agent):
        target = xy + agent.forward_step * np.array([np.cos(heading), np.sin(heading)])
        if grid.segment_is_navigable(xy, target):
            return True
    return False


def sample_distractors(
    rng: np.random.Generator,
    cells: np.ndarray,
    goals: Sequence[Goal],
    count: int,
    constraints: EpisodeConstraints,
    z: float,
) -> tuple[Goal, ...] | None:
    """``count`` distractors on navigable ``cells`` away from the goals, or None if none fit."""
    ok = np.ones(len(cells), dtype=bool)
    for goal in goals:
        ok &= (
            np.hypot(*(cells - np.asarray(goal.position[:2])).T)
            >= constraints.min_distractor_separation
        )
    free = [c for c in range(NUM_CATEGORIES) if c not in {g.category for g in goals}]
    categories = rng.choice(free, size=count, replace=False)
    placed: list[Goal] = []
    for category in categories:
        candidates = np.flatnonzero(ok)
        if len(candidates) == 0:
            return None
        point = cells[candidates[rng.integers(len(candidates))]]
        ok &= np.hypot(*(cells - point).T) >= constraints.min_goal_separation
        placed.append(
            Goal(int(category), (round(float(point[0]), 4), round(float(point[1]), 4), z))
        )
    return tuple(placed)


def iter_chunks(items: Sequence[Any], count: int) -> Iterator[tuple[int, int]]:
    """Split ``count`` items as evenly as possible over ``len(items)`` buckets: ``(index, n)``."""
    base, extra = divmod(count, len(items))
    for index in range(len(items)):
        yield index, base + (1 if index < extra else 0)


def check_on_grid(episode: Episode, grid: NavGrid) -> None:
    """Raise :class:`BadEpisodeError` for a start off the navigable cells, or a goal or
    distractor off the scene's grid (it would be drawn and mapped nowhere)."""
    start = np.asarray(episode.start_position[:2], dtype=np.float64)
    if not bool(grid.is_navigable(start)):
        raise BadEpisodeError(
            f"episode {episode.episode_id}: start_position {episode.start_position} is not "
            f"navigable in {episode.scene_id}"
        )
    rows, cols = grid.shape
    low_x, low_y = grid.origin
    high_x, high_y = low_x + cols * grid.cell_size, low_y + rows * grid.cell_size
    for kind, goals in (("goals", episode.goals), ("distractors", episode.distractors)):
        for index, goal in enumerate(goals):
            if not bool(grid.lookup(grid.inside, np.asarray(goal.position[:2]), outside=False)):
                raise BadEpisodeError(
                    f"episode {episode.episode_id}: {kind}[{index}].position "
                    f"({goal.position[0]:g}, {goal.position[1]:g}) is off the floor of "
                    f"{episode.scene_id}: allowed points of its floor, within x in "
                    f"[{low_x:.2f}, {high_x:.2f}], y in [{low_y:.2f}, {high_y:.2f}] metres"
                )
