"""The database side of runs: creating them under a quota, saving their state at every step
(compare-and-set on ``Run.version``), recording episodes and finishing runs.

Every function here is blocking (SQLAlchemy sessions); the run service calls them in a thread.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any, cast

from sqlalchemy import Connection, CursorResult, func, select, update
from sqlalchemy.orm import Session

from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.leaderboard.models import EpisodeRecord, Run, Team, utcnow
from multion.leaderboard.results import CUT_SHORT, missed_metrics, summarize
from multion.leaderboard.storage import daily_quota_reopens, runs_counted
from multion_client import errors
from multion_client.run_protocol import RunStatus

BASELINE_TEAM = "baselines"
"""The organisers' team whose runs are the leaderboard's baselines."""


@dataclass
class LaneState:
    """One lane of a run: the episode it plays now (or last), as saved at every step.

    A run with K environments plays K episodes at once, one per lane; lane k plays the run's
    episodes k, k + K, k + 2K … (the server's choice, not the client's).
    """

    position: int = -1
    """The run-order number of the lane's current (or last) episode; -1 before its first."""
    episode_active: bool = False
    seq: int = 0
    actions: list[int] = field(default_factory=list)
    last_metrics: dict[str, Any] | None = None
    deadline: dt.datetime | None = None
    consecutive_timeouts: int = 0

    def to_json(self) -> dict[str, Any]:
        return {
            "position": self.position,
            "episode_active": self.episode_active,
            "seq": self.seq,
            "actions": "".join(str(a) for a in self.actions),
            "last_metrics": self.last_metrics,
            "deadline": None if self.deadline is None else self.deadline.isoformat(),
            "consecutive_timeouts": self.consecutive_timeouts,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> LaneState:
        deadline = data.get("deadline")
        return cls(
            position=int(data["position"]),
            episode_active=bool(data["episode_active"]),
            seq=int(data["seq"]),
            actions=[int(c) for c in data["actions"]],
            last_metrics=data.get("last_metrics"),
            deadline=None if deadline is None else dt.datetime.fromisoformat(deadline),
            consecutive_timeouts=int(data["consecutive_timeouts"]),
        )


@dataclass
class RunState:
    """The resumable state of a running run, as saved in its row at every step: a version
    number (compare-and-set) and its lanes."""

    version: int = 0
    lanes: list[LaneState] = field(default_factory=lambda: [LaneState()])

    @classmethod
    def of(cls, run: Run) -> RunState:
        if run.lanes:
            lanes = [LaneState.from_json(lane) for lane in run.lanes]
        else:  # one lane, in the row's own columns (runs stored before lanes existed)
            lanes = [
                LaneState(
                    position=run.position,
                    episode_active=run.episode_active,
                    seq=run.seq,
                    actions=[int(c) for c in run.actions],
                    last_metrics=run.last_metrics,
                    deadline=run.deadline,
                    consecutive_timeouts=run.consecutive_timeouts,
                )
            ]
        return cls(version=run.version, lanes=lanes)

    def columns(self) -> dict[str, Any]:
        """The row's columns: every lane, the earliest deadline (what the expiry loop looks
        for), and lane 0 in the single-lane columns (what older readers know)."""
        first = self.lanes[0]
        deadlines = [lane.deadline for lane in self.lanes if lane.deadline is not None]
        return {
            "lanes": [lane.to_json() for lane in self.lanes],
            "position": first.position,
            "episode_active": first.episode_active,
            "seq": first.seq,
            "actions": "".join(str(a) for a in first.actions),
            "last_metrics": first.last_metrics,
            "deadline": min(deadlines) if deadlines else None,
            "consecutive_timeouts": first.consecutive_timeouts,
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
    if refuse_over_quota(session, run.team_id, track, phase, now, check_quota):
        run.baseline = True
    session.add(run)


def refuse_over_quota(
    session: Session,
    team_id: int,
    track: Track,
    phase: Phase,
    now: dt.datetime,
    check_quota: bool = True,
) -> bool:
    """Raise :class:`~multion_client.errors.QuotaExceeded` if the team may start no further
    run of ``phase`` at ``now``; returns whether the team is the baselines' (no quota). Called
    before a run's simulator is opened too, so an over-quota request costs the workers nothing.
    """
    # Serialise quota checks of one team across replicas (PostgreSQL row lock; SQLite has a
    # single writer anyway).
    team = session.execute(select(Team.name).where(Team.id == team_id).with_for_update())
    if team.scalar_one() == BASELINE_TEAM:
        return True
    if check_quota and phase.daily_quota is not None:
        used = runs_counted(session, team_id, track.name, phase.name, now - dt.timedelta(days=1))
        if used >= phase.daily_quota:
            reopens = daily_quota_reopens(
                session, team_id, track.name, phase.name, now, phase.daily_quota
            )
            raise errors.QuotaExceeded(
                f"{track.name}/{phase.name}: {used} runs in the last 24 hours, the daily quota is "
                f"{phase.daily_quota}; the next run is allowed from {reopens:%Y-%m-%d %H:%M:%S} "
                f"UTC (in {_duration(reopens - now)}); abandoned runs count, runs the server "
                "broke are refunded"
            )
    if check_quota and phase.total_quota is not None:
        used = runs_counted(session, team_id, track.name, phase.name, None)
        if used >= phase.total_quota:
            raise errors.QuotaExceeded(
                f"{track.name}/{phase.name}: {used} runs, the phase's total quota is "
                f"{phase.total_quota}: no further run of this phase is allowed (runs the server "
                "broke are refunded)"
            )
    return False


def _duration(span: dt.timedelta) -> str:
    """A wait as "5 h 3 min" (minutes rounded up: never earlier than the time stated)."""
    minutes = max(1, -(-int(span.total_seconds()) // 60))
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes} min" if hours else f"{minutes} min"


def save_state(
    session: Session | Connection, run_id: str, state: RunState, results: list[EpisodeResult]
) -> None:
    """Write ``state`` (and any newly ended episodes: ``session`` must then be an ORM session)
    if nobody else changed the run meanwhile; raises :class:`RunMoved` otherwise (the caller's
    transaction is then rolled back). Bumps ``state.version``."""
    # execute() is typed as returning a Result; an UPDATE's is a CursorResult (with rowcount)
    done = cast(
        CursorResult[Any],
        session.execute(
            update(Run)
            .where(Run.id == run_id, Run.version == state.version, Run.state == "running")
            .values(version=state.version + 1, **state.columns())
        ),
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
    # completed: played to their end, as the pages count them (results.played_to_end); not
    # the placeholders of episodes never played or cut short when the run ended (or broke)
    done = session.scalar(
        select(func.count())
        .select_from(EpisodeRecord)
        .where(EpisodeRecord.run_id == run.id, EpisodeRecord.end_reason.not_in(CUT_SHORT))
    )
    lanes = [
        {"episode": lane.position, "episode_active": lane.episode_active, "seq": lane.seq}
        for lane in RunState.of(run).lanes
    ]
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
        episodes_done=int(done or 0),
        episode=run.position,
        episode_active=run.episode_active,
        seq=run.seq,
        created_at=run.created_at.isoformat(),
        finished_at=None if run.finished_at is None else run.finished_at.isoformat(),
        refunded=run.refunded,
        baseline=run.baseline,
        results=run.summary if visible else None,
        episodes=per_episode,
        num_envs=run.num_envs,
        lanes=lanes,
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
