"""``window_means``: what ``progress.csv`` says of the recent training episodes, on hand-made
episode summaries."""

from __future__ import annotations

import math
from collections import deque

import pytest
import torch

from multion_agents.learned.episode_stats import window_means

REACH = 1.5


def episode(success: float, closest: float | None, wrong_founds: int = 0) -> dict[str, float]:
    summary = {"success": success, "progress": success, "spl": 0.0, "ppl": 0.0, "steps": 10.0}
    summary["return"] = 3.0 * success
    if closest is not None:  # a server without the ending measures gives neither
        summary |= {"closest_to_goal": closest, "wrong_founds": float(wrong_founds)}
    return summary


def test_the_shares_within_reach_and_with_a_wrong_found() -> None:
    window = deque(
        [
            episode(1.0, 0.0),  # found: within reach
            episode(0.0, 1.2),  # step limit, stood within reach and did not call FOUND
            episode(0.0, REACH),  # step limit, exactly at the success distance
            episode(0.0, 3.0),  # step limit, never near
            episode(0.0, 2.0, wrong_founds=1),  # a wrong FOUND far from the goal
            episode(0.0, None),  # an older server: counted in the means, not in the shares
        ]
    )
    means = window_means(window, torch.device("cpu"), REACH)
    assert means["episodes"] == 6
    assert means["train_success"] == pytest.approx(1 / 6)
    assert means["train_return"] == pytest.approx(0.5)
    assert means["train_within_reach"] == pytest.approx(3 / 5)
    assert means["train_wrong_found"] == pytest.approx(1 / 5)


def test_no_episodes_give_nan_not_an_error() -> None:
    means = window_means(deque(), torch.device("cpu"), REACH)
    assert means["episodes"] == 0
    assert all(math.isnan(means[k]) for k in ("train_success", "train_within_reach"))
    only_old = window_means(deque([episode(1.0, None)]), torch.device("cpu"), REACH)
    assert only_old["train_success"] == 1.0 and math.isnan(only_old["train_within_reach"])
