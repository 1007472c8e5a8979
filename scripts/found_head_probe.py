"""Does a FOUND head's input tell "the goal within reach and in view" apart better than the
trained head does? (issue 51)

Plays episodes of train houses and of val houses with the checkpoint (sampled actions, the
head's gate as trained), records the GRU output the head reads and the label ("FOUND would
succeed and the frame shows the goal": ``goal_distance`` and ``goal_mask``), fits a
class-balanced logistic probe on the train-house steps and scores it and the trained head on
the val-house steps: ROC AUC, and recall and precision at probability 0.5. A probe far better
than the head says the head's training, not what the agent carries, holds FOUND back.

    .venv/bin/python scripts/found_head_probe.py runs/pilot/no-map-found-head-all/checkpoint.pt
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn

from multion_agents.agent import ConfigOverrides
from multion_agents.learned.checkpoint import load_policy
from multion_agents.learned.diagnose import diagnosis_config, play, shows_goal
from multion_agents.learned.policy import PolicyOutput, RecurrentPolicy

LABEL_SENSORS = ("goal_distance", "goal_mask")


@dataclasses.dataclass
class Steps:
    inputs: np.ndarray  # (N, hidden) what the head read
    labels: np.ndarray  # (N,) bool
    head_logits: np.ndarray  # (N,)


def record(policy: RecurrentPolicy, overrides: ConfigOverrides, split: str, episodes: int,
           seed: int, max_steps: int | None) -> Steps:  # fmt: skip
    """``episodes`` episodes of ``split`` played by ``diagnose.play``, step by step."""
    assert policy.found_head is not None
    config = diagnosis_config(overrides, policy.sensors, split)
    sensors = tuple(dict.fromkeys((*config.sensors, *LABEL_SENSORS)))
    task = (
        config.task if max_steps is None else dataclasses.replace(config.task, max_steps=max_steps)
    )
    config = dataclasses.replace(config, sensors=sensors, task=task)
    reach = config.task.success_distance
    captured: list[Tensor] = []
    inputs, labels, logits = [], [], []

    def on_step(episode: int, observation: dict[str, Any], out: PolicyOutput) -> None:
        assert out.found_logit is not None
        inputs.append(captured[-1].reshape(-1).numpy().copy())
        captured.clear()
        logits.append(float(out.found_logit[0, 0]))
        near = float(observation["goal_distance"][0]) <= reach
        labels.append(near and shows_goal(observation))

    hook = policy.found_head.register_forward_hook(lambda _m, i, _o: captured.append(i[0]))
    try:
        play(policy, config, episodes, seed, on_step, progress=True)
    finally:
        hook.remove()
    print(f"{split}: {len(labels)} steps, {sum(labels)} positive", file=sys.stderr)
    return Steps(np.stack(inputs), np.array(labels, dtype=bool), np.array(logits))


def auc(scores: np.ndarray, labels: np.ndarray) -> float:
    """ROC AUC by ranks (nan without both classes)."""
    positives, negatives = int(labels.sum()), int((~labels).sum())
    if not positives or not negatives:
        return math.nan
    ranks = np.empty(len(scores))
    ranks[np.argsort(scores, kind="stable")] = np.arange(1, len(scores) + 1)
    return float((ranks[labels].sum() - positives * (positives + 1) / 2) / (positives * negatives))


def fit_probe(train: Steps, steps: int = 400) -> nn.Linear:
    """A logistic probe on standardised inputs, positives weighed to balance the classes."""
    torch.manual_seed(0)
    mean, scale = train.inputs.mean(0), train.inputs.std(0) + 1e-6
    x = torch.tensor((train.inputs - mean) / scale, dtype=torch.float32)
    y = torch.tensor(train.labels, dtype=torch.float32)
    probe = nn.Linear(x.shape[1], 1)
    with torch.no_grad():  # fold the standardisation into the probe
        probe.weight.zero_()
    optimiser = torch.optim.Adam(probe.parameters(), lr=1e-2, weight_decay=1e-4)
    weight = torch.tensor(float((~train.labels).sum()) / max(int(train.labels.sum()), 1))
    for _ in range(steps):
        optimiser.zero_grad()
        loss = nn.functional.binary_cross_entropy_with_logits(
            probe(x).squeeze(1), y, pos_weight=weight
        )
        loss.backward()
        optimiser.step()
    with torch.no_grad():
        w = probe.weight / torch.tensor(scale, dtype=torch.float32)
        probe.bias -= (w * torch.tensor(mean, dtype=torch.float32)).sum()
        probe.weight.copy_(w)
    return probe


def scores_line(name: str, logits: np.ndarray, labels: np.ndarray) -> str:
    fired = logits > 0
    hits = int((fired & labels).sum())
    recall = hits / labels.sum() if labels.any() else math.nan
    precision = hits / fired.sum() if fired.any() else math.nan
    return (f"  {name:<34} AUC {auc(logits, labels):.3f}, at 0.5: recall {recall:.2f}, "
            f"precision {precision:.2f}, {int(fired.sum())} steps fire")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint", help="a checkpoint trained with --found-head")
    parser.add_argument("--episodes", type=int, default=30, help="per split (default 30)")
    parser.add_argument("--max-steps", type=int, default=None, help="episode step limit")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if not 1 <= args.episodes <= 1000:
        parser.error(f"--episodes must be in [1, 1000], got {args.episodes}")
    torch.set_num_threads(1)
    policy, overrides, _model = load_policy(args.checkpoint)
    if policy.found_head is None:
        parser.error(f"{args.checkpoint} has no FOUND head (trained without --found-head)")
    policy.eval()
    train = record(policy, overrides, "train", args.episodes, args.seed, args.max_steps)
    val = record(policy, overrides, "val", args.episodes, args.seed + 1, args.max_steps)
    probe = fit_probe(train)
    with torch.no_grad():
        probe_logits = probe(torch.tensor(val.inputs, dtype=torch.float32)).squeeze(1).numpy()
    print(f"{args.checkpoint}: {len(train.labels)} train-house steps ({int(train.labels.sum())} "
          f"with the goal in view within reach), {len(val.labels)} val-house steps "
          f"({int(val.labels.sum())}); scored on the val-house steps:")  # fmt: skip
    print(scores_line("the trained head", val.head_logits, val.labels))
    print(scores_line("a balanced probe of its input", probe_logits, val.labels))
    firing = int((val.head_logits > 0).sum())
    if firing:
        top = np.argsort(-probe_logits)[:firing]
        print(f"  the probe's {firing} highest steps (as many as the head fires): precision "
              f"{val.labels[top].mean():.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
