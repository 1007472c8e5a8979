"""Replaying a stored run in-process: the hidden episodes regenerated from the secret, the
stored actions played again, the metrics compared with (or re-scored over) the stored ones."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from sqlalchemy.orm import Session

from multion.config.codec import session_config_from_dict
from multion.leaderboard.challenge import Challenge
from multion.leaderboard.hidden import HiddenEpisodes
from multion.leaderboard.live_run import draw_of
from multion.leaderboard.models import EpisodeRecord, Run
from multion.leaderboard.results import missed_metrics, summarize
from multion.leaderboard.storage import StorageError
from multion.task.env import MultiONEnv
from multion.task.measures import SCORING_SENSORS, metrics_as_stored


@dataclass(frozen=True)
class ReplayedEpisode:
    position: int
    stored: dict[str, Any]
    replayed: dict[str, Any]
    steps: int | None = None
    """The stored actions played again in the simulator; None: not played by the run (or
    expired before it started), so compared as stored."""

    @property
    def same(self) -> bool:
        return self.stored == metrics_as_stored(self.replayed, self.stored)


def replay_run(challenge: Challenge, run: Run, progress: bool = False) -> Iterator[ReplayedEpisode]:
    """Each played episode of ``run`` replayed from its stored actions, in run order.

    An episode that ended by a timeout or an abandon keeps that end reason (the replay ends
    where the actions end); missed episodes (no actions) are compared as stored. An episode
    that expired before its client started it was stored as the server's placeholder
    (:func:`~multion.leaderboard.results.missed_metrics`): its replay is that placeholder again,
    since resetting the episode would give metrics the run never had.
    """
    track = challenge.track(run.track)
    phase = track.phase(run.phase) if track is not None else None
    if track is None or phase is None:
        raise StorageError(
            f"run {run.id}: the challenge has no track/phase {run.track}/{run.phase}"
        )
    hidden, draw = HiddenEpisodes(challenge, in_subprocess=False), draw_of(run)
    ids = hidden.episode_ids(track, phase, draw)
    config = track.env_config(phase, SCORING_SENSORS, run.maps)
    env_config, _ = session_config_from_dict(config)
    env: MultiONEnv | None = None
    try:
        for record in run.episodes:
            if record.end_reason == "not_played":
                yield ReplayedEpisode(record.position, record.metrics, record.metrics)
                continue
            placeholder = missed_metrics(track.num_goals, record.end_reason)
            if not record.actions and record.metrics == metrics_as_stored(
                placeholder, record.metrics
            ):
                # never started
                yield ReplayedEpisode(record.position, record.metrics, placeholder)
                continue
            episode = hidden.episode(track, phase, draw, record.position)
            if ids[record.position] != record.episode_id:
                raise StorageError(
                    f"run {run.id}: episode {record.position} was {record.episode_id}, the "
                    f"secret now gives {ids[record.position]}: wrong secret?"
                )
            if env is None:
                env = MultiONEnv(env_config, episodes=[episode])
            _, info = env.reset(options={"episode": episode})
            for action in record.actions:
                _, _, terminated, truncated, info = env.step(int(action))
            metrics = dict(info["metrics"])
            if record.end_reason not in ("success", "wrong_found", "max_steps"):
                metrics["end_reason"] = record.end_reason  # timeout / abandoned: the run's
            yield ReplayedEpisode(record.position, record.metrics, metrics, len(record.actions))
    finally:
        if env is not None:
            env.close()


def rescore(session: Session, challenge: Challenge, run_id: str, write: bool) -> dict[str, Any]:
    """Replay run ``run_id``; with ``write``, store the replayed metrics and new aggregates.

    Returns ``{"run_id", "episodes", "replayed", "steps", "refunded", "differences":
    [positions], "summary"}``: ``episodes`` is the run's count (the summary's), ``replayed`` those played
    again in the simulator (the run played them, to their end or not) with ``steps`` actions.
    """
    run = session.get(Run, run_id)
    if run is None:
        raise StorageError(f"no run {run_id!r}")
    if run.state == "running":
        raise StorageError(f"run {run_id} is still running; replay it once it is over")
    track = challenge.track(run.track)
    assert track is not None
    replayed = list(replay_run(challenge, run))
    differences = [r.position for r in replayed if not r.same]
    summary = summarize([r.replayed for r in replayed], track.metric)
    if write:
        records = {r.position: r for r in session.query(EpisodeRecord).filter_by(run_id=run_id)}
        for r in replayed:
            records[r.position].metrics = r.replayed
        run.summary = summary
    return {
        "run_id": run_id,
        "episodes": len(replayed),
        "replayed": sum(1 for r in replayed if r.steps is not None),
        "steps": sum(r.steps or 0 for r in replayed),
        "refunded": run.refunded,
        "differences": differences,
        "summary": summary,
    }
