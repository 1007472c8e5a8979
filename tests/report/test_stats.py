"""The report's interval estimates: bootstrap, paired and independent differences."""

from __future__ import annotations

import numpy as np
import pytest

from multion_agents.report.stats import bootstrap, independent_difference, paired_difference


def test_bootstrap_brackets_the_mean_and_stays_in_range() -> None:
    values = [0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.0]
    estimate = bootstrap(values)
    assert estimate.mean == pytest.approx(np.mean(values))
    assert 0.0 <= estimate.low < estimate.mean < estimate.high <= 1.0
    assert bootstrap(values) == estimate  # fixed seed: the same interval every time
    constant = bootstrap([0.5] * 7)
    assert (constant.mean, constant.low, constant.high) == (0.5, 0.5, 0.5)


def test_paired_difference_of_a_sample_with_itself_is_exactly_zero() -> None:
    values = np.random.default_rng(3).random(50)
    difference = paired_difference(values, values)
    assert (difference.mean, difference.low, difference.high) == (0.0, 0.0, 0.0)
    assert not difference.excludes_zero()


def test_pairing_narrows_the_interval() -> None:
    rng = np.random.default_rng(0)
    difficulty = rng.random(200)  # shared by both agents: pairing cancels it
    a = difficulty + 0.05
    b = difficulty + rng.normal(0.0, 0.01, 200)
    paired = paired_difference(a, b)
    unpaired = independent_difference(a, b)
    assert paired.mean == pytest.approx(unpaired.mean)
    assert paired.excludes_zero() and not unpaired.excludes_zero()
    assert paired.high - paired.low < (unpaired.high - unpaired.low) / 5


def test_paired_samples_must_have_equal_length() -> None:
    with pytest.raises(ValueError, match="differ in length"):
        paired_difference([1.0, 0.0], [1.0])
