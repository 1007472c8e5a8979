"""A run's aggregates (mean and 95% bootstrap interval per metric) and the leaderboard rows."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any

import numpy as np

SUMMARY_METRICS = ("ppl", "progress", "success", "spl")
RESAMPLES = 2000
CI_METHOD = f"percentile bootstrap over episodes, {RESAMPLES} resamples, 95%"


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
    """Mean of ``values`` with a 95% percentile-bootstrap interval (seeded: reproducible)."""
    data = np.asarray(values, dtype=np.float64)
    if data.size == 0:
        return {"mean": 0.0, "low": 0.0, "high": 0.0}
    rng = np.random.default_rng(seed)
    means = data[rng.integers(0, data.size, size=(RESAMPLES, data.size))].mean(axis=1)
    low, high = np.percentile(means, [2.5, 97.5])
    return {"mean": float(data.mean()), "low": float(low), "high": float(high)}


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
