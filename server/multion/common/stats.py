"""Means with 95% percentile-bootstrap intervals, shared by the leaderboard and ``multion report``.

2,000 resamples of the episodes with a fixed seed: no normality assumption, intervals inside the
range of the data (inside [0, 1] for rates like Success), and the same numbers every time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

RESAMPLES = 2000
CI_METHOD = f"percentile bootstrap over episodes, {RESAMPLES} resamples, 95%"

# one value per episode: a list or a 1-d array
Samples = Sequence[float] | np.ndarray


@dataclass(frozen=True)
class Estimate:
    """A mean and its 95% confidence interval (fractions, not percent)."""

    mean: float
    low: float
    high: float

    def excludes_zero(self) -> bool:
        return self.low > 0 or self.high < 0

    def overlaps(self, other: Estimate) -> bool:
        return self.low <= other.high and other.low <= self.high


NAN = Estimate(float("nan"), float("nan"), float("nan"))


def resampled_means(data: np.ndarray, resamples: int, seed: int) -> np.ndarray:
    """Means of ``resamples`` resamples (with replacement) of ``data``, seeded."""
    rng = np.random.default_rng(seed)
    means: np.ndarray = data[rng.integers(len(data), size=(resamples, len(data)))].mean(axis=1)
    return means


def bootstrap(values: Samples, resamples: int = RESAMPLES, seed: int = 0) -> Estimate:
    """Mean of ``values`` with a 95% percentile-bootstrap interval (NAN for no values)."""
    data = np.asarray(values, dtype=np.float64)
    if len(data) == 0:
        return NAN
    low, high = np.percentile(resampled_means(data, resamples, seed), [2.5, 97.5])
    return Estimate(float(data.mean()), float(low), float(high))
