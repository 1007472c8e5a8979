"""Re-scoring a ``multion eval`` run: its recorded actions played again with today's measures.

The task gains measures (``cells_visited``, ``closest_to_goal``, ``current_goal_seen``) after
runs were evaluated. Since the simulator is deterministic, a run's episodes can be played again
from ``episodes.jsonl`` (same dataset, config and actions) without its agent: each replay must
reproduce every metric the run recorded, and then the measures the run lacks are added to its
lines. Nothing is rendered (metrics do not depend on the camera), so a 100-episode run takes
seconds, not the evaluation's hours. A run none of whose episodes replays exactly is left as it
was, and the error names the first episode that differs.
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from multion.common.files import write_atomically
from multion.config.episode import Episode
from multion.task.env import MultiONEnv
from multion.task.measures import SCORING_SENSORS
from multion.video.replay import replay_steps
from multion.video.stored import VideoError
from multion_agents.report.run_summary import versions
from multion_agents.video.recorded import (
    EPISODES_FILE,
    METRICS_FILE,
    RecordedEpisode,
    RecordedRun,
    dataset_episodes,
    replay_env,
)


class RescoreError(VideoError):
    """A run that cannot be re-scored; the message names the run and what stands in the way."""


@dataclass(frozen=True)
class Rescored:
    """What re-scoring a run gave: the lines of its new ``episodes.jsonl`` and the measures
    they gained."""

    run: RecordedRun
    lines: list[dict[str, Any]]
    added: list[str]


def replayed_metrics(
    env: MultiONEnv, episode: Episode, recorded: RecordedEpisode
) -> dict[str, Any]:
    """The final metrics of ``recorded``'s actions played again in ``env`` (as JSON stores
    them), checked by :func:`~multion.video.replay.replay_steps` against the recorded ones; a
    RescoreError too when the episode has not ended after its last action."""
    steps = replay_steps(env, episode, recorded.actions, recorded.metrics, recorded.episode_id)
    ((_, info, _),) = deque(steps, maxlen=1)  # played to the end, where the check runs
    replayed: dict[str, Any] = json.loads(json.dumps(info["metrics"]))
    if replayed.get("end_reason") is None:
        raise RescoreError(
            f"episode {recorded.episode_id}: the replay had not ended after its "
            f"{len(recorded.actions)} recorded actions"
        )
    return replayed


def rescore_run(run: RecordedRun, on_episode: Callable[[], None] | None = None) -> Rescored:
    """Every episode of ``run`` played again and checked; its lines with the measures the run
    lacked added after the recorded ones (recorded values are kept as they were)."""
    episodes = dataset_episodes(run)
    lines = [json.loads(line) for line in (run.path / EPISODES_FILE).read_text().splitlines()]
    added: list[str] = []
    env = replay_env(run, SCORING_SENSORS)
    try:
        for line, recorded in zip(lines, run.episodes, strict=True):
            episode = episodes.get(recorded.episode_id)
            if episode is None:
                raise RescoreError(f"{run.dataset} has no episode {recorded.episode_id!r}")
            replayed = replayed_metrics(env, episode, recorded)
            new = [key for key in replayed if key not in recorded.metrics]
            line["metrics"] = {**recorded.metrics, **{key: replayed[key] for key in new}}
            added += [key for key in new if key not in added]
            if on_episode is not None:
                on_episode()
    finally:
        env.close()
    return Rescored(run, lines, added)


def write_rescored(rescored: Rescored) -> list[Path]:
    """Replace the run's ``episodes.jsonl`` with the re-scored lines and note in its
    ``metrics.json`` (``run.rescored``) which measures were added, by which versions; each file
    is replaced atomically, the episodes first. Nothing is written when nothing was added."""
    if not rescored.added:
        return []
    episodes_path = rescored.run.path / EPISODES_FILE
    write_atomically(episodes_path, "".join(json.dumps(line) + "\n" for line in rescored.lines))
    metrics_path = rescored.run.path / METRICS_FILE
    payload = json.loads(metrics_path.read_text(encoding="utf-8"))
    payload["run"].setdefault("rescored", []).append(
        {"added": rescored.added, "versions": versions()}
    )
    write_atomically(metrics_path, json.dumps(payload, indent=2) + "\n")
    return [episodes_path, metrics_path]
