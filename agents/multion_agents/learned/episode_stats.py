"""What the training log reports of the recent training episodes (``progress.csv``'s
``train_*`` columns), summed over every rank."""

from __future__ import annotations

import math
from collections import deque

import torch

from multion_agents.learned.distributed import sum_over_ranks
from multion_agents.learned.rollout_envs import ENDING_METRICS, SUMMARY_METRICS


def window_means(
    window: deque[dict[str, float]], device: torch.device, reach: float
) -> dict[str, float]:
    """The recent training episodes' means, over all ranks; ``train_within_reach``: the share
    that came within ``reach`` of the goal they ended on (success included), and
    ``train_wrong_found``: the share with a wrong FOUND (of those whose server gives both)."""
    names = [*SUMMARY_METRICS, "return"]
    ending = [e for e in window if all(k in e for k in ENDING_METRICS)]
    sums = [sum(e.get(k, 0.0) for e in window) for k in names] + [
        float(sum(e["closest_to_goal"] <= reach for e in ending)),
        float(sum(e["wrong_founds"] > 0 for e in ending)),
        float(len(ending)),
        float(len(window)),
    ]
    sums = sum_over_ranks(sums, device)
    *totals, within_reach, wrong_found, with_ending, count = sums
    means = {
        f"train_{k}": (s / count if count else math.nan) for k, s in zip(names, totals, strict=True)
    }
    means["train_within_reach"] = within_reach / with_ending if with_ending else math.nan
    means["train_wrong_found"] = wrong_found / with_ending if with_ending else math.nan
    return {"episodes": count, **means}
