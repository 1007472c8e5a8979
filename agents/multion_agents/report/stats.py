"""Means with 95% bootstrap intervals: one sample (:mod:`multion.common.stats`, shared with the
leaderboard), two independent samples, and paired samples.

All intervals are percentile bootstrap intervals (2,000 resamples, fixed seed): no normality
assumption, and they stay inside the range of the data (inside [0, 1] for rates like Success).
"""

from __future__ import annotations

import numpy as np

# the one-sample estimate is the leaderboard's too; the report's modules import it from here
from multion.common.stats import (  # noqa: F401
    CI_METHOD,
    NAN,
    RESAMPLES,
    Estimate,
    Samples,
    bootstrap,
    resampled_means,
)

# metric key in info["metrics"] → column title (the paper's Table 3 columns)
HEADLINE: tuple[tuple[str, str], ...] = (
    ("success", "Success"),
    ("progress", "Progress"),
    ("spl", "SPL"),
    ("ppl", "PPL"),
)


def paired_difference(
    first: Samples, second: Samples, resamples: int = RESAMPLES, seed: int = 0
) -> Estimate:
    """Mean of ``first - second`` over the same episodes, resampling episodes (not runs).

    Pairing removes the variance that comes from episodes being easy or hard for both agents,
    so the interval is much narrower than that of two independent means.
    """
    a, b = np.asarray(first, dtype=np.float64), np.asarray(second, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"paired samples differ in length: {len(a)} and {len(b)}")
    return bootstrap(a - b, resamples, seed)


def independent_difference(
    first: Samples, second: Samples, resamples: int = RESAMPLES, seed: int = 0
) -> Estimate:
    """Mean of ``first`` minus mean of ``second`` for two independent samples."""
    a, b = np.asarray(first, dtype=np.float64), np.asarray(second, dtype=np.float64)
    if len(a) == 0 or len(b) == 0:
        return NAN
    differences = resampled_means(a, resamples, seed) - resampled_means(b, resamples, seed + 1)
    low, high = np.percentile(differences, [2.5, 97.5])
    return Estimate(float(a.mean() - b.mean()), float(low), float(high))
