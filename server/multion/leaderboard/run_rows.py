"""The organisers' listings of runs: ``multion leaderboard runs`` (a line per run), ``export``
(a flat row per run, ``--best``: the page's rows) and what ``replay`` says it played. Their
counts are the pages': a run's completed episodes are those played to their end
(:func:`~multion.leaderboard.results.played_to_end`), and a run without a score there (refunded,
or none completed) shows none here either."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from multion.leaderboard.challenge import Challenge
from multion.leaderboard.models import Run, Team, utcnow
from multion.leaderboard.results import SUMMARY_METRICS, played_to_end
from multion.leaderboard.web.queries import leaderboards

NO_SCORE = "–"
"""What the pages show for a run without a score."""


def counted(n: int, noun: str) -> str:
    """``1 episode``, ``4 episodes``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def run_rows(
    session: Session,
    team: str | None = None,
    track: str | None = None,
    phase: str | None = None,
    state: str | None = None,
) -> list[dict[str, Any]]:
    """Every run (or those matching the filters given) as a flat row: team, track, phase,
    method, state, episodes (the run's) and episodes_completed (played to their end, as the
    leaderboard page's "1 / 4"; None while running), metrics with intervals."""
    query = select(Run, Team.name).join(Team).order_by(Run.created_at)
    for column, value in ((Run.track, track), (Run.phase, phase), (Run.state, state)):
        if value:
            query = query.where(column == value)
    if team:
        query = query.where(Team.name == team)
    rows = []
    for run, team_name in session.execute(query):
        row: dict[str, Any] = {
            "run_id": run.id,
            "team": team_name,
            "track": run.track,
            "phase": run.phase,
            "method": run.method,
            "baseline": run.baseline,
            "state": run.state,
            "end_reason": run.end_reason,
            "refunded": run.refunded,
            "episodes": len(run.order),
            "episodes_completed": None if run.summary is None else played_to_end(run.summary),
            "created_at": run.created_at.isoformat(),
            "finished_at": run.finished_at.isoformat() if run.finished_at else None,
            "paper_url": run.paper_url,
            "code_url": run.code_url,
        }
        for metric in SUMMARY_METRICS:
            estimate = (run.summary or {}).get(metric) or {}
            for part in ("mean", "low", "high"):
                row[f"{metric}_{part}"] = estimate.get(part)
        row["primary"] = (run.summary or {}).get("primary")
        rows.append(row)
    return rows


def shown_rows(
    session: Session, challenge: Challenge, rows: list[dict[str, Any]]
) -> list[dict[str, Any]]:
    """The rows of the runs the leaderboard page shows now, in its order: the page's own query
    (:func:`~multion.leaderboard.web.queries.leaderboards`), so sealed phases before their
    date and runs that played nothing are left out here too. Each row starts with the page's
    ``rank`` and ``overlaps_leader`` (its 95% interval of the ranking metric overlaps the
    leader's; marked, as on the page, on the rows ranked below 1)."""
    by_id = {row["run_id"]: row for row in rows}
    boards = leaderboards(session, challenge, utcnow())
    return [
        {"rank": r.rank, "overlaps_leader": r.tied_with_leader and r.rank > 1, **by_id[r.run_id]}
        for board in boards
        for r in board.rows
        if r.run_id in by_id
    ]


def run_line(row: dict[str, Any]) -> str:
    """A :func:`run_rows` row as ``multion leaderboard runs`` prints it: its episodes completed
    of the run's, and its ranking metric, or "–" where the pages show none (a refunded run: the
    server broke it; a run that completed no episode)."""
    mark = " [baseline]" if row["baseline"] else ""
    reason = f" ({row['end_reason']})" if row["end_reason"] else ""
    if row["refunded"]:  # the server's fault: the run does not count against the quota
        reason += ", refunded"
    line = f"{row['run_id']}  {row['team']}{mark}  {row['track']}/{row['phase']}  {row['method']}  {row['state']}{reason}"
    completed, primary = row["episodes_completed"], row["primary"]
    if completed is not None:
        line += f"  {completed}/{counted(row['episodes'], 'episode')} completed"
    if primary is not None:
        scored = not row["refunded"] and bool(completed)
        line += f"  {primary} " + (f"{100 * row[primary + '_mean']:.1f}%" if scored else NO_SCORE)
    return line


def replay_counts(report: dict[str, Any]) -> str:
    """What a replay (:func:`~multion.leaderboard.replay.rescore`'s report) played: "1 of 4
    episodes replayed (94 steps); 3 not played (stored as failures); ppl 2.50%"."""
    summary, replayed, episodes = report["summary"], report["replayed"], report["episodes"]
    line = f"{replayed} of {counted(episodes, 'episode')} replayed ({counted(report['steps'], 'step')})"
    if replayed < episodes:
        line += f"; {episodes - replayed} not played (stored as failures)"
    primary = summary["primary"]
    score = f"{primary} {100 * summary[primary]['mean']:.2f}%"
    if report["refunded"]:
        score += " (refunded: the pages show no score)"
    return f"{line}; {score}"
