"""The database side of runs: creating them under a quota, saving their state at every step
(compare-and-set on ``Run.version``), recording episodes and finishing runs.

Every function here is blocking (SQLAlchemy sessions); the run service calls them in a thread.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import Connection, select, update
from sqlalchemy.orm import Session

from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.leaderboard.models import EpisodeRecord, Run, Team, utcnow
from multion.leaderboard.results import missed_metrics, summarize
from multion.leaderboard.storage import runs_counted
from multion_client import errors
from multion_client.protocol import RunStatus

BASELINE_TEAM = "baselines"
"""The organisers' team whose runs are the leaderboard's baselines."""


@dataclass
class RunState:
    """The resumable state of a running run, as saved in its row at every step."""

    version: int = 0
    position: int = -1
    episode_active: bool = False
    seq: int = 0
    actions: list[int] = field(default_factory=list)
    last_metrics: dict[str, Any] | None = None
    deadline: dt.datetime | None = None
    consecutive_timeouts: int = 0

    @classmethod
    def of(cls, run: Run) -> RunState:
        return cls(
            version=run.version,
            position=run.position,
            episode_active=run.episode_active,
            seq=run.seq,
            actions=[int(c) for c in run.actions],
            last_metrics=run.last_metrics,
            deadline=run.deadline,
            consecutive_timeouts=run.consecutive_timeouts,
        )

    def columns(self) -> dict[str, Any]:
        return {
            "position": self.position,
            "episode_active": self.episode_active,
            "seq": self.seq,
            "actions": "".join(str(a) for a in self.actions),
            "last_metrics": self.last_metrics,
            "deadline": self.deadline,
            "consecutive_timeouts": self.consecutive_timeouts,
        }


@dataclass(frozen=True)
class EpisodeResult:
    """One finished (or expired, or missed) episode of a run, to be recorded."""

    position: int
    episode_index: int
    episode_id: str
    end_reason: str
    metrics: dict[str, Any]
    actions: str
    seconds: float


class RunMoved(Exception):
    """The run's row changed under us (another replica or an admin acted on it)."""


def create_run(
    session: Session,
    run: Run,
    track: Track,
    phase: Phase,
    now: dt.datetime,
    check_quota: bool = True,
) -> None:
    """Insert ``run`` if the team's quotas allow (daily: any 24 hours; total: ever).

    The quota is debited here, at creation: an abandoned run still counts. Runs of the
    organisers' team :data:`BASELINE_TEAM` are marked baselines and have no quota.
    """
    # Serialise quota checks of one team across replicas (PostgreSQL row lock; SQLite has a
    # single writer anyway).
    team = session.execute(select(Team.name).where(Team.id == run.team_id).with_for_update())
    if team.scalar_one() == BASELINE_TEAM:
        run.baseline, check_quota = True, False
    if check_quota and phase.daily_quota is not None:
        used = runs_counted(
            session, run.team_id, track.name, phase.name, now - dt.timedelta(days=1)
        )
        if used >= phase.daily_quota:
            raise errors.QuotaExceeded(
                f"{track.name}/{phase.name}: {used} runs in the last 24 hours, the daily quota is "
                f"{phase.daily_quota}; abandoned runs count, runs the server broke are refunded"
            )
    if check_quota and phase.total_quota is not None:
        used = runs_counted(session, run.team_id, track.name, phase.name, None)
        if used >= phase.total_quota:
            raise errors.QuotaExceeded(
                f"{track.name}/{phase.name}: {used} runs, the phase's total quota is "
                f"{phase.total_quota}"
            )
    session.add(run)


def save_state(
    session: Session | Connection, run_id: str, state: RunState, results: list[EpisodeResult]
) -> None:
    """Write ``state`` (and any newly ended episodes: ``session`` must then be an ORM session)
    if nobody else changed the run meanwhile; raises :class:`RunMoved` otherwise (the caller's
    transaction is then rolled back). Bumps ``state.version``."""
    done = session.execute(
        update(Run)
        .where(Run.id == run_id, Run.version == state.version, Run.state == "running")
        .values(version=state.version + 1, **state.columns())
    )
    if done.rowcount != 1:
        raise RunMoved(run_id)
    for result in results:
        assert isinstance(session, Session)
        session.add(_record(run_id, result))
    state.version += 1


def finish_run(
    session: Session,
    run_id: str,
    state: RunState,
    results: list[EpisodeResult],
    outcome: str,
    end_reason: str | None,
    track: Track,
    episode_ids: list[str],
    order: list[int],
    refunded: bool = False,
) -> dict[str, Any]:
    """End the run: record ``results``, fill the episodes never played as failures, store the
    aggregates. ``outcome``: finished, ended or failed. Returns the summary."""
    save_state(session, run_id, state, results)
    recorded = {
        r.position
        for r in session.scalars(select(EpisodeRecord).where(EpisodeRecord.run_id == run_id))
    }
    recorded |= {r.position for r in results}
    for position, index in enumerate(order):
        if position not in recorded:
            reason = "not_played"
            session.add(
                _record(
                    run_id,
                    EpisodeResult(
                        position,
                        index,
                        episode_ids[position],
                        reason,
                        missed_metrics(track.num_goals, reason),
                        "",
                        0.0,
                    ),  # fmt: skip
                )
            )
    session.flush()
    records = session.scalars(
        select(EpisodeRecord).where(EpisodeRecord.run_id == run_id).order_by(EpisodeRecord.position)
    ).all()
    summary = summarize([r.metrics for r in records], track.metric)
    run = session.get(Run, run_id)
    assert run is not None
    run.state, run.end_reason, run.refunded = outcome, end_reason, refunded
    run.finished_at, run.summary = utcnow(), summary
    run.episode_active, run.deadline = False, None
    return summary


def describe_run(
    session: Session, challenge: Challenge, run: Run, episodes: bool = True
) -> RunStatus:
    """A run's status, with the results its phase lets the team see."""
    track = challenge.track(run.track)
    phase = track.phase(run.phase) if track is not None else None
    # A refunded run (the server broke it) shows nothing: its partial results would be a free
    # evaluation for anyone who can make a worker die.
    visible = phase is not None and phase.results_visible(utcnow()) and not run.refunded
    done = session.scalar(
        select(EpisodeRecord.position)
        .where(EpisodeRecord.run_id == run.id)
        .order_by(EpisodeRecord.position.desc())
        .limit(1)
    )
    per_episode = None
    if episodes and visible and phase is not None and phase.feedback == "episodes":
        per_episode = [
            {"episode": r.position, "metrics": r.metrics}
            for r in session.scalars(
                select(EpisodeRecord)
                .where(EpisodeRecord.run_id == run.id)
                .order_by(EpisodeRecord.position)
            )
        ]
    return RunStatus(
        run_id=run.id,
        track=run.track,
        phase=run.phase,
        method=run.method,
        state=run.state,
        end_reason=run.end_reason,
        num_episodes=len(run.order),
        episodes_done=0 if done is None else done + 1,
        episode=run.position,
        episode_active=run.episode_active,
        seq=run.seq,
        created_at=run.created_at.isoformat(),
        finished_at=None if run.finished_at is None else run.finished_at.isoformat(),
        refunded=run.refunded,
        baseline=run.baseline,
        results=run.summary if visible else None,
        episodes=per_episode,
    )


def _record(run_id: str, result: EpisodeResult) -> EpisodeRecord:
    metrics = dict(result.metrics)
    metrics["end_reason"] = result.end_reason
    return EpisodeRecord(
        run_id=run_id,
        position=result.position,
        episode_index=result.episode_index,
        episode_id=result.episode_id,
        end_reason=result.end_reason,
        metrics=metrics,
        actions=result.actions,
        seconds=result.seconds,
    )
