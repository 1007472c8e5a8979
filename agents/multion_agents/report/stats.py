"""Means with 95% bootstrap intervals: one sample, two independent samples, and paired samples.

All intervals are percentile bootstrap intervals (2,000 resamples, fixed seed): no normality
assumption, and they stay inside the range of the data (inside [0, 1] for rates like Success).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# metric key in info["metrics"] → column title (the paper's Table 3 columns)
HEADLINE: tuple[tuple[str, str], ...] = (
    ("success", "Success"),
    ("progress", "Progress"),
    ("spl", "SPL"),
    ("ppl", "PPL"),
)
RESAMPLES = 2000
CI_METHOD = f"percentile bootstrap over episodes, {RESAMPLES} resamples, 95%"


@dataclass(frozen=True)
class Estimate:
    """A mean and its 95% confidence interval (fractions, not percent)."""

    mean: float
    low: float
    high: float

    def excludes_zero(self) -> bool:
        return self.low > 0 or self.high < 0


NAN = Estimate(float("nan"), float("nan"), float("nan"))


def _resampled_means(data: np.ndarray, resamples: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return data[rng.integers(len(data), size=(resamples, len(data)))].mean(axis=1)


def bootstrap(values: Sequence[float], resamples: int = RESAMPLES, seed: int = 0) -> Estimate:
    """Mean of ``values`` with a 95% percentile-bootstrap interval."""
    data = np.asarray(values, dtype=np.float64)
    if len(data) == 0:
        return NAN
    low, high = np.percentile(_resampled_means(data, resamples, seed), [2.5, 97.5])
    return Estimate(float(data.mean()), float(low), float(high))


def paired_difference(
    first: Sequence[float], second: Sequence[float], resamples: int = RESAMPLES, seed: int = 0
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
    first: Sequence[float], second: Sequence[float], resamples: int = RESAMPLES, seed: int = 0
) -> Estimate:
    """Mean of ``first`` minus mean of ``second`` for two independent samples."""
    a, b = np.asarray(first, dtype=np.float64), np.asarray(second, dtype=np.float64)
    if len(a) == 0 or len(b) == 0:
        return NAN
    differences = _resampled_means(a, resamples, seed) - _resampled_means(b, resamples, seed + 1)
    low, high = np.percentile(differences, [2.5, 97.5])
    return Estimate(float(a.mean() - b.mean()), float(low), float(high))
