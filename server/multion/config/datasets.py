"""Episode datasets: task names, the packaged datasets' paths, and reading, checking and
writing dataset files (SPEC §5). Light: numpy and the configs, no scene or simulator, so the
server process, the eval and train settings and the report can read them cheaply; the online
sampler that fills these files is :mod:`multion.task.sampling`.

File format (``*.json.gz``)::

    {"format": "multion-episodes", "version": 3, "scene_generator_version": 2,
     "num_goals": 3, "num_distractors": 0, "split": "val",
     "generator": {...}, "episodes": [Episode.to_dict(), ...]}

``version`` is the file format's; ``scene_generator_version`` the version of the procedural houses
the episodes were sampled in (:data:`multion.config.scenes.GENERATOR_VERSION`). A file whose
house episodes were made for other houses is refused: its starts and goals would not fit.
Version 3 files hold only episodes whose goals the agent's own steps reach
(:attr:`EpisodeConstraints.step_paths`); version 2 files did not check it, and version 1 files
were made for the first houses.
"""

from __future__ import annotations

import gzip
import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from multion.common.files import replacing
from multion.config.episode import Episode
from multion.config.errors import UsageError
from multion.config.ranges import ConfigError
from multion.config.scenes import GENERATOR_VERSION
from multion_client.constants import NUM_CATEGORIES
from multion_client.errors import InvalidConfig


class DatasetError(UsageError, InvalidConfig, ValueError):
    """A dataset file that cannot be used; the message names the file and the problem (422
    ``invalid_config``: the config's ``dataset``)."""


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
        raise ConfigError(f"unknown task {name!r}: use 1-on … {NUM_CATEGORIES}-on")
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


def dataset_sha256(path: Path) -> str:
    """SHA-256 of a dataset file: tells runs over different dataset versions apart."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


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
    text = json.dumps(payload, separators=(",", ":")).encode("utf-8")
    # GzipFile with no name and no time: the bytes depend on the episodes alone
    with replacing(path) as temporary, temporary.open("wb") as raw:
        with gzip.GzipFile(filename="", fileobj=raw, mode="wb", mtime=0) as handle:
            handle.write(text)
    return path


def _describe(error: Exception) -> str:
    if isinstance(error, KeyError):
        return f"missing field {error.args[0]!r}"
    return str(error)
