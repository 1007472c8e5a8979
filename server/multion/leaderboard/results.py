"""A run's aggregates (mean and 95% bootstrap interval per metric) and the leaderboard rows."""

from __future__ import annotations

import datetime as dt
import math
from collections import Counter
from collections.abc import Callable, Hashable, Iterable, Sequence
from typing import Any, TypeVar

from multion.common import stats
from multion.common.stats import CI_METHOD

SUMMARY_METRICS = ("ppl", "progress", "success", "spl")
RANKED_STATES = ("finished", "ended")
"""Runs that count on a leaderboard: played to the end, or ended early (the missing episodes
count as failures). Failed runs were the server's fault and are refunded."""

T = TypeVar("T")
NEVER = dt.datetime.max.replace(tzinfo=dt.timezone.utc)


def entrant(team: str, method: str, baseline: bool) -> tuple[str, str]:
    """Whose best run a leaderboard row shows: a team's, or each method's of the baselines."""
    return (team, method if baseline else "")


def best_first(score: float, state: str, finished_at: dt.datetime | None, run_id: str) -> tuple:
    """Sort key of the one "best run" rule (the leaderboard page and ``export --best``): the
    highest score, then a finished run before an ended one (same score, all episodes played),
    then the earliest to finish, then the run id (so the choice never depends on query order)."""
    finished = finished_at or NEVER
    return (-score, 0 if state == "finished" else 1, finished, run_id)


def keep_best(
    runs: Iterable[T], key: Callable[[T], Hashable], order: Callable[[T], tuple]
) -> dict[Hashable, T]:
    """The best run per key: the first by ``order`` (a :func:`best_first` key)."""
    best: dict[Hashable, T] = {}
    for run in runs:
        k = key(run)
        if k not in best or order(run) < order(best[k]):
            best[k] = run
    return best


def competition_ranks(scores: Sequence[float]) -> list[int]:
    """Ranks of scores sorted best first, equal scores sharing a rank ("1, 1, 3").

    Scores are compared exactly: a run's mean is a correctly rounded sum of its per-episode
    values (:func:`bootstrap`), so runs with the same per-episode values, in any order, have
    the same mean to the last bit."""
    ranks: list[int] = []
    for position, score in enumerate(scores):
        ranks.append(ranks[-1] if ranks and score == scores[position - 1] else position + 1)
    return ranks


CUT_SHORT = ("not_played", "abandoned")
"""End reasons of the episodes a run did not play to their end: missed, or cut short because
the run ended (abandoned, or the server broke it)."""


def played_to_end(summary: dict[str, Any]) -> int:
    """Episodes of a run (its ``summary``) played to their end: not those missed or cut short
    because the run ended. A run with none is no leaderboard entry and has no score to draw."""
    reasons = summary.get("end_reasons") or {}
    cut = sum(int(reasons.get(reason) or 0) for reason in CUT_SHORT)
    return int(summary.get("episodes") or 0) - cut


def missed_metrics(num_goals: int, end_reason: str) -> dict[str, Any]:
    """The record of an episode that was not played (a run that ended early): a failure."""
    return {
        "steps": 0,
        "collisions": 0,
        "path_length": 0.0,
        "distance_to_goal": None,
        "closest_to_goal": None,
        "goals_found": 0,
        "wrong_founds": 0,
        "progress": 0.0,
        "success": 0.0,
        "spl": 0.0,
        "ppl": 0.0,
        "path_length_at_found": 0.0,
        "ppl_reference": 0.0,
        "seen_before_current": [],
        "current_goal_seen": False,
        "cells_visited": 0,
        "end_reason": end_reason,
    }


def bootstrap(values: Sequence[float], seed: int = 0) -> dict[str, float]:
    """:func:`multion.common.stats.bootstrap` as stored in a run's summary (zeros for no values)."""
    if len(values) == 0:
        return {"mean": 0.0, "low": 0.0, "high": 0.0}
    # Canonical order: the same per-episode values give the same interval whatever order the
    # episodes were played in; the mean is an exact (correctly rounded) sum over the count.
    canonical = sorted(float(v) for v in values)
    estimate = stats.bootstrap(canonical, seed=seed)
    mean = math.fsum(canonical) / len(canonical)
    return {"mean": mean, "low": estimate.low, "high": estimate.high}


def estimate(values: Sequence[float]) -> stats.Estimate:
    """:func:`bootstrap` as an :class:`~multion.common.stats.Estimate` (the pages' breakdowns)."""
    value = bootstrap(values)
    return stats.Estimate(value["mean"], value["low"], value["high"])


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
