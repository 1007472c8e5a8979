"""A run's aggregates (mean and 95% bootstrap interval per metric) and the leaderboard rows."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Hashable, Iterable, Sequence
from typing import Any, TypeVar

from multion import stats
from multion.stats import CI_METHOD

SUMMARY_METRICS = ("ppl", "progress", "success", "spl")
RANKED_STATES = ("finished", "ended")
"""Runs that count on a leaderboard: played to the end, or ended early (the missing episodes
count as failures). Failed runs were the server's fault and are refunded."""

T = TypeVar("T")


def entrant(team: str, method: str, baseline: bool) -> tuple[str, str]:
    """Whose best run a leaderboard row shows: a team's, or each method's of the baselines."""
    return (team, method if baseline else "")


def keep_best(
    runs: Iterable[T], key: Callable[[T], Hashable], score: Callable[[T], float]
) -> dict[Hashable, T]:
    """The highest-scoring run per key (the first seen on equal scores)."""
    best: dict[Hashable, T] = {}
    for run in runs:
        k = key(run)
        if k not in best or score(run) > score(best[k]):
            best[k] = run
    return best


def missed_metrics(num_goals: int, end_reason: str) -> dict[str, Any]:
    """The record of an episode that was not played (a run that ended early): a failure."""
    return {
        "steps": 0,
        "collisions": 0,
        "path_length": 0.0,
        "distance_to_goal": None,
        "goals_found": 0,
        "wrong_founds": 0,
        "progress": 0.0,
        "success": 0.0,
        "spl": 0.0,
        "ppl": 0.0,
        "path_length_at_found": 0.0,
        "ppl_reference": 0.0,
        "seen_before_current": [],
        "end_reason": end_reason,
    }


def bootstrap(values: Sequence[float], seed: int = 0) -> dict[str, float]:
    """:func:`multion.stats.bootstrap` as stored in a run's summary (zeros for no values)."""
    if len(values) == 0:
        return {"mean": 0.0, "low": 0.0, "high": 0.0}
    estimate = stats.bootstrap(values, seed=seed)
    return {"mean": estimate.mean, "low": estimate.low, "high": estimate.high}


def summarize(records: Sequence[dict[str, Any]], primary: str) -> dict[str, Any]:
    """Aggregates of a run's per-episode metrics (every episode of the run, missed ones too)."""
    summary: dict[str, Any] = {
        "episodes": len(records),
        "primary": primary,
        "ci": CI_METHOD,
        "end_reasons": dict(Counter(str(r.get("end_reason")) for r in records)),
    }
    for name in SUMMARY_METRICS:
        summary[name] = bootstrap([float(r.get(name) or 0.0) for r in records])
    return summary
