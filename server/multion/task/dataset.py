"""Episode datasets: gzipped JSON files, their validation, and the seeded generator (SPEC §5).

File format (``*.json.gz``)::

    {"format": "multion-episodes", "version": 3, "scene_generator_version": 2,
     "num_goals": 3, "num_distractors": 0, "split": "val",
     "generator": {...}, "episodes": [Episode.to_dict(), ...]}

``version`` is the file format's; ``scene_generator_version`` the version of the procedural houses
the episodes were sampled in (:data:`multion.scenes.registry.GENERATOR_VERSION`). A file whose
house episodes were made for other houses is refused: its starts and goals would not fit.
Version 3 files hold only episodes whose goals the agent's own steps reach
(:attr:`EpisodeConstraints.step_paths`); version 2 files did not check it, and version 1 files
were made for the first houses.
"""

from __future__ import annotations

import gzip
import json
import os
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from multion.config.episode import Episode, Goal
from multion.config.sim import AgentConfig
from multion.config.task import EpisodeConstraints
from multion.scenes.registry import GENERATOR_VERSION
from multion.sim.geodesic import FieldCache, distance_field
from multion.sim.navgrid import NavGrid
from multion.task.errors import DatasetError
from multion.task.step_reach import step_headings, steps_reach_goals
from multion_client.constants import NUM_CATEGORIES

FORMAT = "multion-episodes"
VERSION = 3
DATA_DIR = Path(__file__).resolve().parent.parent / "data" / "datasets"


def task_name(num_goals: int) -> str:
    return f"{num_goals}-on"


def parse_task(name: str | int) -> int:
    """``"3-on"``, ``"3-ON"``, ``"3on"`` or ``3`` → 3; a clear ``ValueError`` otherwise."""
    text = str(name).strip().lower().replace("_", "-")
    number = (
        text[: -len("-on")] if text.endswith("-on") else text[:-2] if text.endswith("on") else text
    )
    if not number.isdigit() or not 1 <= int(number) <= NUM_CATEGORIES:
        raise ValueError(f"unknown task {name!r}: use 1-on … {NUM_CATEGORIES}-on")
    return int(number)


DISTRACTOR_VARIANT = 3
"""Distractors per episode in the packaged ``m-on-distractors`` datasets and registered
``MultiON/m-ON-distractors-v0`` ids."""


def variant_name(num_goals: int, num_distractors: int = 0) -> str:
    """``3-on``; with the packaged number of distractors ``3-on-distractors``; with another
    number ``3-on-2-distractors`` (the packaged datasets' folders; the last are not shipped)."""
    if num_distractors == 0:
        return task_name(num_goals)
    if num_distractors == DISTRACTOR_VARIANT:
        return f"{task_name(num_goals)}-distractors"
    return f"{task_name(num_goals)}-{num_distractors}-distractors"


def packaged_dataset_path(num_goals: int, split: str, num_distractors: int = 0) -> Path:
    return DATA_DIR / variant_name(num_goals, num_distractors) / f"{split}.json.gz"


def read_header(path: str | Path) -> dict[str, Any]:
    """A dataset file's header (everything but the episodes), checked for format and version."""
    data = _read(Path(path))
    return {k: v for k, v in data.items() if k != "episodes"}


def _read(path: Path) -> dict[str, Any]:
    try:
        with gzip.open(path, "rt", encoding="utf-8") as handle:
            data = json.load(handle)
    except FileNotFoundError:
        raise DatasetError(f"{path}: no such dataset file") from None
    except (OSError, EOFError, json.JSONDecodeError, UnicodeDecodeError) as error:
        raise DatasetError(f"{path}: not a readable gzipped JSON dataset ({error})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise DatasetError(f'{path}: not a MultiON dataset (expected "format": "{FORMAT}")')
    if data.get("version") != VERSION:
        raise DatasetError(
            f"{path}: dataset version {data.get('version')!r} is not supported (expected "
            f"{VERSION}): version 1 files were made for the old houses, and version 2 files may "
            "hold episodes whose goals the agent's steps cannot reach; regenerate it with "
            "`multion dataset generate`"
        )
    return data


def load_dataset(
    path: str | Path, num_goals: int | None = None, num_distractors: int | None = None
) -> list[Episode]:
    """Read and check a dataset file. Raises :class:`DatasetError` naming the file and problem.

    ``num_goals`` / ``num_distractors``, when given, must match every episode.
    """
    path = Path(path)
    data = _read(path)
    raw = data.get("episodes")
    if not isinstance(raw, list) or not raw:
        raise DatasetError(f'{path}: "episodes" must be a non-empty list')
    made_by = data.get("scene_generator_version")
    houses = any(
        str(item.get("scene_id", "")).startswith("house-") for item in raw if isinstance(item, dict)
    )
    if houses and made_by != GENERATOR_VERSION:
        raise DatasetError(
            f"{path}: its episodes were sampled in houses of scene generator version {made_by!r}, "
            f"but this server builds version {GENERATOR_VERSION}: the houses differ, so its starts "
            "and goals do not fit them; regenerate it with `multion dataset generate`"
        )
    expected = num_goals if num_goals is not None else data.get("num_goals")
    extra = num_distractors if num_distractors is not None else data.get("num_distractors", 0)
    episodes = []
    seen_ids: set[str] = set()
    for index, item in enumerate(raw):
        try:
            episode = Episode.from_dict(item)
        except (KeyError, TypeError, ValueError) as error:
            raise DatasetError(f"{path}: episode {index}: malformed ({_describe(error)})") from None
        problem = check_episode(episode, expected)
        if problem is None and len(episode.distractors) != extra:
            problem = (
                f"has {len(episode.distractors)} distractors, expected {extra} "
                "(task.num_distractors must match the dataset)"
            )
        if problem is None and episode.episode_id in seen_ids:
            problem = "duplicate episode_id"
        if problem:
            raise DatasetError(f"{path}: episode {index} ({episode.episode_id}): {problem}")
        seen_ids.add(episode.episode_id)
        episodes.append(episode)
    return episodes


def check_episode(episode: Episode, num_goals: int | None = None) -> str | None:
    """Structural problems of an episode (geometry is checked when it is loaded in a scene)."""
    if not episode.goals:
        return "has no goals"
    if num_goals is not None and episode.num_goals != num_goals:
        return f"has {episode.num_goals} goals, the dataset is for {num_goals}"
    categories = [g.category for g in episode.goals]
    bad = [c for c in categories if not 0 <= c < NUM_CATEGORIES]
    if bad:
        return f"goal category {bad[0]} is not in 0..{NUM_CATEGORIES - 1}"
    if len(set(categories)) != len(categories):
        return f"goal categories {categories} repeat (they are sampled without replacement)"
    others = [d.category for d in episode.distractors]
    bad = [c for c in others if not 0 <= c < NUM_CATEGORIES]
    if bad:
        return f"distractor category {bad[0]} is not in 0..{NUM_CATEGORIES - 1}"
    if len(set(others)) != len(others) or set(others) & set(categories):
        return f"distractor categories {others} repeat or overlap the goal categories {categories}"
    values = [
        *episode.start_position,
        episode.start_yaw,
        *(v for g in (*episode.goals, *episode.distractors) for v in g.position),
    ]
    if not all(np.isfinite(values)):
        return "has a non-finite coordinate"
    return None


def save_dataset(
    path: str | Path,
    episodes: Sequence[Episode],
    num_goals: int,
    split: str,
    generator: dict[str, Any] | None = None,
    num_distractors: int = 0,
) -> Path:
    """Write a dataset atomically (temp file + rename), so a crash leaves no half-written file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": FORMAT,
        "version": VERSION,
        "scene_generator_version": GENERATOR_VERSION,
        "num_goals": num_goals,
        "num_distractors": num_distractors,
        "split": split,
        "generator": generator or {},
        "episodes": [e.to_dict() for e in episodes],
    }
    fd, tmp = tempfile.mkstemp(suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) as handle:
            handle.write(json.dumps(payload, separators=(",", ":")).encode("utf-8"))
        os.chmod(tmp, 0o644)  # mkstemp makes owner-only files; datasets are meant to be shared
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return path


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
        distractors = (
            sample_distractors(rng, cells, goals, num_distractors, constraints, z)
            if num_distractors
            else ()
        )
        if distractors is None:
            continue
        start_xy = (round(float(start[0]), 4), round(float(start[1]), 4))
        start_yaw = round(float(rng.uniform(-np.pi, np.pi)), 6)
        if constraints.mobile_start and not can_step(grid, np.asarray(start_xy), start_yaw):
            continue
        if constraints.step_paths and not steps_reach_goals(
            grid, np.asarray(start_xy), start_yaw, goal_fields, constraints.reach
        ):
            continue
        return Episode(
            episode_id=episode_id,
            scene_id=scene_id,
            start_position=(*start_xy, z),
            start_yaw=start_yaw,
            goals=goals,
            geodesic_distances=tuple(measured),
            distractors=distractors,
        )
    return None


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


def _describe(error: Exception) -> str:
    if isinstance(error, KeyError):
        return f"missing field {error.args[0]!r}"
    return str(error)


def iter_chunks(items: Sequence[Any], count: int) -> Iterator[tuple[int, int]]:
    """Split ``count`` items as evenly as possible over ``len(items)`` buckets: ``(index, n)``."""
    base, extra = divmod(count, len(items))
    for index in range(len(items)):
        yield index, base + (1 if index < extra else 0)
