"""A ``multion eval`` run directory read back for filming, and its episodes replayed.

A video is made from the recorded actions, not during the evaluation: the episode is reset from
the same dataset, with the same environment config, and the actions of ``episodes.jsonl`` are
played again in this process with an RGB-D camera. The simulator is deterministic, so the same
run gives the same frames, and a replay whose final metrics differ from the recorded ones is
refused (a different dataset file or simulator version would film something that never
happened).
"""

from __future__ import annotations

import copy
import hashlib
import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from multion.config.codec import session_config_from_dict
from multion.config.datasets import DatasetError, load_dataset, packaged_dataset_path, parse_task
from multion.config.episode import Episode
from multion.config.ranges import ConfigError
from multion.task.env import MultiONEnv
from multion.video.replay import StepView
from multion.video.replay import replay as replay_steps
from multion.video.stored import FILMED_SENSORS, VideoError
from multion_client.constants import NUM_ACTIONS

METRICS_FILE = "metrics.json"
EPISODES_FILE = "episodes.jsonl"


@dataclass(frozen=True)
class RecordedEpisode:
    """One line of ``episodes.jsonl``."""

    index: int
    episode_id: str
    metrics: dict[str, Any]
    recorded_actions: tuple[int, ...] | None
    """None in runs written before actions were recorded."""

    @property
    def actions(self) -> tuple[int, ...]:
        """The actions played; a VideoError for a run that did not record them."""
        if self.recorded_actions is None:
            raise VideoError(
                f"episode {self.episode_id} has no recorded actions (the run predates them): "
                "evaluate it again to replay or film it"
            )
        return self.recorded_actions


@dataclass(frozen=True)
class RecordedRun:
    """What a replay needs of a run directory."""

    path: Path
    agent: str
    num_goals: int
    env_config: dict[str, Any]
    """The config the episodes were played with (``run.env_config`` of metrics.json)."""
    dataset: Path
    dataset_sha256: str
    """The played dataset file's SHA-256 ('' for runs that did not record it)."""
    episodes: tuple[RecordedEpisode, ...]

    def episode(self, episode_id: str) -> RecordedEpisode:
        """The recorded episode ``episode_id``; a VideoError listing some ids otherwise."""
        for episode in self.episodes:
            if episode.episode_id == episode_id:
                return episode
        ids = [e.episode_id for e in self.episodes]
        shown = ", ".join(ids[:5]) + (f" … ({len(ids)} in all)" if len(ids) > 5 else "")
        raise VideoError(f"{self.path} has no episode {episode_id!r}; its episodes: {shown}")


def read_run(path: Path, dataset: Path | None = None) -> RecordedRun:
    """The run in directory ``path``; ``dataset`` replaces the recorded dataset path (a run
    filmed on another machine). A VideoError names what is missing or unreadable."""
    if not path.is_dir():
        raise VideoError(f"{path} is not a directory (give the --out directory of `multion eval`)")
    run = _read_json(path / METRICS_FILE).get("run")
    if not isinstance(run, dict) or not isinstance(run.get("env_config"), dict):
        raise VideoError(f"{path / METRICS_FILE} has no run.env_config: not a `multion eval` run")
    episodes = tuple(_read_episodes(path / EPISODES_FILE))
    try:
        num_goals = parse_task(str(run.get("task", "")))
    except ValueError as error:
        raise VideoError(f"{path / METRICS_FILE}: run.task: {error}") from None
    if dataset is not None:
        if not dataset.is_file():
            what = "is a directory" if dataset.is_dir() else "does not exist"
            raise VideoError(
                f"--dataset {dataset} {what}: give the dataset file the run played "
                f"(a .json.gz; {path / METRICS_FILE} names it as run.dataset)"
            )
    else:
        recorded = run.get("dataset")
        dataset = (
            Path(recorded)
            if isinstance(recorded, str)
            else Path(packaged_dataset_path(num_goals, str(run.get("split"))))
        )
        if not dataset.is_file():
            raise VideoError(
                f"{path}: the run's dataset {dataset} is not here; give its file with --dataset"
            )
    return RecordedRun(
        path=path,
        agent=str(run.get("agent", "?")),
        num_goals=num_goals,
        env_config=run["env_config"],
        dataset=dataset,
        dataset_sha256=str(run.get("dataset_sha256") or ""),
        episodes=episodes,
    )


def _read_json(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise VideoError(f"{path} does not exist: not a `multion eval` run directory") from None
    except (OSError, ValueError) as error:
        raise VideoError(f"{path} cannot be read: {error}") from None
    if not isinstance(data, dict):
        raise VideoError(f"{path} is not a JSON object")
    return data


def _read_episodes(path: Path) -> Iterator[RecordedEpisode]:
    try:
        lines = path.read_text().splitlines()
    except FileNotFoundError:
        raise VideoError(f"{path} does not exist: not a `multion eval` run directory") from None
    for number, line in enumerate(lines, start=1):
        try:
            record = json.loads(line)
            episode_id, metrics = str(record["episode_id"]), dict(record["metrics"])
        except (ValueError, KeyError, TypeError) as error:
            raise VideoError(f"{path} line {number} is not an episode record: {error}") from None
        yield RecordedEpisode(
            index=int(record.get("index", number - 1)),
            episode_id=episode_id,
            metrics=metrics,
            recorded_actions=_parse_actions(record.get("actions"), f"{path} line {number}"),
        )


def _parse_actions(text: Any, where: str) -> tuple[int, ...] | None:
    if text is None:
        return None
    if not isinstance(text, str) or not all(c.isdigit() and int(c) < NUM_ACTIONS for c in text):
        raise VideoError(f"{where}: 'actions' must be a string of digits 0-{NUM_ACTIONS - 1}")
    return tuple(int(c) for c in text)


# ---------------------------------------------------------------------- replay
def dataset_episode(run: RecordedRun, episode_id: str) -> Episode:
    """Episode ``episode_id`` of the run's dataset, after checking the file is the one played."""
    episode = dataset_episodes(run).get(episode_id)
    if episode is None:
        raise VideoError(f"{run.dataset} has no episode {episode_id!r}")
    return episode


def dataset_episodes(run: RecordedRun) -> dict[str, Episode]:
    """The run's dataset by episode id, after checking the file is the one played."""
    if run.dataset_sha256:
        digest = hashlib.sha256(run.dataset.read_bytes()).hexdigest()
        if digest != run.dataset_sha256:
            raise VideoError(
                f"{run.dataset} is not the dataset the run played (SHA-256 {digest[:12]}…, the "
                f"run recorded {run.dataset_sha256[:12]}…)"
            )
    try:
        episodes = load_dataset(run.dataset, run.num_goals)
    except DatasetError as error:
        raise VideoError(f"{run.dataset}: {error}") from None
    return {episode.episode_id: episode for episode in episodes}


def replay_env(run: RecordedRun, sensors: Sequence[str] = FILMED_SENSORS) -> MultiONEnv:
    """An in-process environment with the run's config and ``sensors`` (by default an RGB-D
    camera; metrics do not depend on what is rendered)."""
    config = copy.deepcopy(run.env_config)
    config["sensors"] = list(sensors)
    config.pop("dataset", None)  # the episode is given inline
    try:
        env_config, _ = session_config_from_dict(config)
    except ConfigError as error:
        raise VideoError(f"{run.path / METRICS_FILE}: run.env_config: {error}") from None
    return MultiONEnv(env_config, episodes=[])


def replay(env: MultiONEnv, episode: Episode, recorded: RecordedEpisode) -> Iterator[StepView]:
    """The start and each step of ``recorded`` played again in ``env``; a VideoError at the end
    when the replayed metrics are not the recorded ones."""
    return replay_steps(env, episode, recorded.actions, recorded.metrics, recorded.episode_id)
