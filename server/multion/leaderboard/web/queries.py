"""What the web pages show, read from the results database (blocking: call in a thread).

The leaderboard reads one row per finished run (its stored aggregates, never its episodes), so
its cost grows with the number of runs, not of episodes. Sealed phases give no rows before
their date, and the pages of their runs show no results.
"""

from __future__ import annotations

import datetime as dt
import functools
import re
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from multion.common.stats import Estimate
from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.leaderboard.models import EpisodeRecord, Run, Team
from multion.leaderboard.results import (
    RANKED_STATES,
    SUMMARY_METRICS,
    best_first,
    competition_ranks,
    entrant,
    keep_best,
    played_to_end,
)
from multion.leaderboard.results import estimate as bootstrap
from multion.task.measures import seen_split

METRIC_NAMES = {"ppl": "PPL", "progress": "Progress", "success": "Success", "spl": "SPL"}


def stored(summary: dict[str, Any], metric: str) -> Estimate:
    """A metric's estimate as a run's stored summary holds it (fractions)."""
    value = summary.get(metric) or {}
    return Estimate(
        float(value.get("mean", 0.0)), float(value.get("low", 0.0)), float(value.get("high", 0.0))
    )


@dataclass(frozen=True)
class BoardRow:
    rank: int
    tied_with_leader: bool
    """Its interval of the ranking metric overlaps the leader's (the leader itself too)."""
    team: str
    method: str
    run_id: str
    baseline: bool
    paper_url: str | None
    code_url: str | None
    scores: dict[str, Estimate]
    completed: int
    """Episodes played (not those missed or abandoned in play because the run ended early)."""
    total: int
    date: dt.datetime


@dataclass(frozen=True)
class Board:
    """The leaderboard of one track's phase."""

    track: Track
    phase: Phase
    sealed: bool
    rows: list[BoardRow]


def leaderboards(session: Session, challenge: Challenge, now: dt.datetime) -> list[Board]:
    """One board per track and phase: each team's best run (each baseline method's best for the
    baselines team), ranked by the track's metric; equal means share a rank. The best run and the
    order of rows follow :func:`~multion.leaderboard.results.best_first`, as ``export --best``.

    The database extracts the few numbers needed from each run's aggregates (JSON), so the cost
    is one short row per run."""
    numbers = [
        Run.summary[metric][part].as_float().label(f"{metric}_{part}")
        for metric in SUMMARY_METRICS
        for part in ("mean", "low", "high")
    ]
    query = (
        select(
            Run.id,
            Run.track,
            Run.phase,
            Run.method,
            Run.paper_url,
            Run.code_url,
            Run.baseline,
            Run.state,
            Run.finished_at,
            Team.name,
            *numbers,
            Run.summary["episodes"].as_integer().label("episodes"),
            Run.summary["end_reasons"]["not_played"].as_integer().label("not_played"),
            Run.summary["end_reasons"]["abandoned"].as_integer().label("abandoned"),
        )  # fmt: skip
        .join(Team)
        .where(Run.state.in_(RANKED_STATES), Run.summary.is_not(None))
    )
    by_board: dict[tuple[str, str], list[Any]] = defaultdict(list)
    for row in session.execute(query):
        if _completed(row) > 0:  # a run that played nothing (abandoned at once) is no entry
            by_board[(row.track, row.phase)].append(row)
    boards = []
    for track in challenge.tracks:
        column = f"{track.metric}_mean"
        for phase in track.phases:
            sealed = not phase.results_visible(now)
            best = keep_best(
                by_board[(track.name, phase.name)],
                key=lambda r: entrant(r.name, r.method, bool(r.baseline)),
                order=functools.partial(_order, column=column),
            )
            runs = [] if sealed else list(best.values())
            boards.append(Board(track, phase, sealed, _ranked(runs, track.metric)))
    return boards


def _completed(row: Any) -> int:
    """Episodes played to their end: not those missed or cut short because the run ended."""
    return int(row.episodes or 0) - int(row.not_played or 0) - int(row.abandoned or 0)


def _order(row: Any, column: str) -> tuple:
    return best_first(getattr(row, column) or 0.0, row.state, row.finished_at, row.id)


def _scores(row: Any) -> dict[str, Estimate]:
    return {
        m: Estimate(
            *(float(getattr(row, f"{m}_{part}") or 0.0) for part in ("mean", "low", "high"))
        )
        for m in SUMMARY_METRICS
    }


def _ranked(runs: Sequence[Any], metric: str) -> list[BoardRow]:
    column = f"{metric}_mean"
    scored = [(_scores(r), r) for r in sorted(runs, key=lambda r: _order(r, column))]
    ranks = competition_ranks([scores[metric].mean for scores, _ in scored])
    rows: list[BoardRow] = []
    leader = scored[0][0][metric] if scored else None
    for rank, (scores, run) in zip(ranks, scored, strict=True):
        total = int(run.episodes or 0)
        rows.append(
            BoardRow(
                rank=rank,
                tied_with_leader=leader is not None and scores[metric].overlaps(leader),
                team=run.name,
                method=run.method,
                run_id=run.id,
                baseline=bool(run.baseline),
                paper_url=run.paper_url,
                code_url=run.code_url,
                scores=scores,
                completed=_completed(run),
                total=total,
                date=run.finished_at,
            )
        )
    return rows


# ---------------------------------------------------------------------- a run
@dataclass(frozen=True)
class SeenSplit:
    """Goal k found after goal k-1, split by whether goal k was seen before (the supplement's
    backtracking analysis): share found and number of episodes in each group."""

    goal: int
    seen: Estimate | None
    seen_n: int
    not_seen: Estimate | None
    not_seen_n: int


@dataclass(frozen=True)
class Breakdown:
    """Aggregates over a group of a run's episodes (e.g. those of one hidden house)."""

    label: str
    episodes: int
    scores: dict[str, Estimate]


@dataclass
class RunPage:
    run: Run
    team: str
    track: Track | None
    phase: Phase | None
    visible: bool
    """Results may be shown (not a sealed phase before its date)."""
    scores: dict[str, Estimate] = field(default_factory=dict)
    end_reasons: dict[str, int] = field(default_factory=dict)
    seen_splits: list[SeenSplit] = field(default_factory=list)
    records: list[EpisodeRecord] = field(default_factory=list)
    """Per-episode records, on phases with per-episode feedback only."""

    @property
    def per_episode(self) -> bool:
        return self.visible and self.phase is not None and self.phase.feedback == "episodes"


def run_page(
    session: Session, challenge: Challenge, run_id: str, now: dt.datetime
) -> RunPage | None:
    found = session.execute(select(Run, Team.name).join(Team).where(Run.id == run_id)).first()
    if found is None:
        return None
    run, team = found
    track = challenge.track(run.track)
    phase = track.phase(run.phase) if track is not None else None
    visible = (  # a refunded run (the server broke it) shows nothing: no free evaluation
        phase is not None and phase.results_visible(now) and run.summary is not None
        and not run.refunded
    )  # fmt: skip
    page = RunPage(run, team, track, phase, visible)
    if not visible:
        return page
    page.scores = {m: stored(run.summary, m) for m in SUMMARY_METRICS}
    page.end_reasons = dict(run.summary.get("end_reasons") or {})
    records = list(
        session.scalars(
            select(EpisodeRecord)
            .where(EpisodeRecord.run_id == run.id)
            .order_by(EpisodeRecord.position)
        )
    )
    if track is not None:
        page.seen_splits = seen_splits([r.metrics for r in records], track.num_goals)
    if page.per_episode:
        page.records = records
    return page


def seen_splits(metrics: Sequence[dict[str, Any]], num_goals: int) -> list[SeenSplit]:
    """For k = 2..m, among episodes that found goal k-1: found goal k, seen before or not."""
    splits = []
    for goal in range(2, num_goals + 1):
        seen, unseen = seen_split(metrics, goal)
        splits.append(
            SeenSplit(
                goal,
                bootstrap(seen) if seen else None,
                len(seen),
                bootstrap(unseen) if unseen else None,
                len(unseen),
            )
        )
    return splits


def breakdown(records: Sequence[EpisodeRecord], label_of: dict[int, str]) -> list[Breakdown]:
    """Aggregates per label (``label_of``: hidden episode index → label, e.g. its house)."""
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for record in records:
        groups[label_of.get(record.episode_index, "?")].append(record.metrics)
    return [
        Breakdown(
            label,
            len(group),
            {m: bootstrap([float(x.get(m) or 0.0) for x in group]) for m in SUMMARY_METRICS},
        )
        for label, group in sorted(groups.items(), key=lambda item: _natural(item[0]))
    ]


# ---------------------------------------------------------------------- a team
@dataclass(frozen=True)
class TeamRun:
    run_id: str
    track: str
    phase: str
    method: str
    state: str
    baseline: bool
    created_at: dt.datetime
    finished_at: dt.datetime | None
    primary: Estimate | None
    """The track's ranking metric, if its phase shows results now and the run played an
    episode to its end."""


def team_runs(
    session: Session, challenge: Challenge, team: str, now: dt.datetime
) -> list[TeamRun] | None:
    """The team's runs, newest first (None: no such team)."""
    team_id = session.scalar(select(Team.id).where(Team.name == team))
    if team_id is None:
        return None
    query = (
        select(
            Run.id,
            Run.track,
            Run.phase,
            Run.method,
            Run.state,
            Run.baseline,
            Run.created_at,
            Run.finished_at,
            Run.summary,
            Run.refunded,
        )  # fmt: skip
        .where(Run.team_id == team_id)
        .order_by(Run.created_at.desc())
    )
    runs = []
    for row in session.execute(query):
        track = challenge.track(row.track)
        phase = track.phase(row.phase) if track is not None else None
        # the leaderboard's rule: a run that played no episode to its end has no score
        shown = (
            phase is not None and phase.results_visible(now) and row.summary is not None
            and not row.refunded and played_to_end(row.summary) > 0
        )  # fmt: skip
        runs.append(
            TeamRun(
                row.id,
                row.track,
                row.phase,
                row.method,
                row.state,
                bool(row.baseline),
                row.created_at,
                row.finished_at,
                stored(row.summary, track.metric) if shown and track is not None else None,
            )  # fmt: skip
        )
    return runs


def _natural(label: str) -> list[Any]:
    """Sort key that puts "house 2" before "house 10"."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", label)]
