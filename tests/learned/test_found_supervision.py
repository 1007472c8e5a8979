"""``--found-supervision`` (issue 51): labels from the goal_distance oracle, the class-balanced
loss against hand computation, its direction, and that only training receives the oracle."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import pytest
import torch
from test_recipe_options import tiny_args

from multion_agents.learned.checkpoint import CheckpointError, load_policy
from multion_agents.learned.found_supervision import (
    FOUND_LABEL_SENSOR,
    class_weights,
    found_labels,
    found_loss,
    found_probabilities,
    found_targets,
    mean_where,
)
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_run import run_env_config, train
from multion_client.constants import Action


def test_labels_say_where_found_would_succeed() -> None:
    distance = torch.tensor([[[0.4], [1.5]], [[1.51], [1e6]]])  # (T, B, 1) readings
    assert found_labels(distance, 1.5).tolist() == [1.0, 1.0, 0.0, 0.0]
    assert found_labels(distance, 1.0).tolist() == [1.0, 0.0, 0.0, 0.0]


def test_the_loss_weighs_each_class_half_as_computed_by_hand() -> None:
    logits = torch.tensor([[2.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 3.0, 0.0]])
    labels = torch.tensor([1.0, 0.0, 0.0])  # one positive, two negatives
    weights = class_weights(labels)
    assert weights == pytest.approx((3 / 2, 3 / 4))  # N / (2 N_pos), N / (2 N_neg)
    p_found = torch.softmax(logits, dim=1)[:, int(Action.FOUND)]
    positive = -torch.log(p_found[0])
    negative = -(torch.log(1 - p_found[1]) + torch.log(1 - p_found[2])) / 2
    expected = (positive + negative) / 2
    assert weights is not None
    assert float(found_loss(logits, labels, weights)) == pytest.approx(float(expected), rel=1e-5)


def test_a_rollouts_targets_keep_its_steps_and_weigh_its_classes() -> None:
    distance = torch.full((3, 2, 1), 4.0)  # (T, B, 1) goal_distance readings
    distance[1, 0] = 1.0
    targets = found_targets(distance, 1.5)
    assert targets.labels.tolist() == [[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]]
    assert targets.weights == pytest.approx((6 / 2, 6 / 10))
    assert found_targets(torch.full((3, 2, 1), 4.0), 1.5).weights is None


def test_a_rollout_without_both_classes_teaches_nothing() -> None:
    assert class_weights(torch.zeros(64)) is None  # no step at a goal: no "never FOUND" lesson
    assert class_weights(torch.ones(8)) is None


def test_classes_weigh_half_over_the_rollout_not_each_mini_batch() -> None:
    """Mini-batches without a positive (most of them) must not each teach "never FOUND" with the
    whole weight: summed over a rollout's mini-batches, the loss is the rollout's balanced one."""
    generator = torch.Generator().manual_seed(0)
    logits = torch.randn(16, 4, 4, generator=generator)  # (T, B, A)
    labels = torch.zeros(16, 4)
    labels[3:6, 2] = 1.0  # every positive in env 2
    weights = class_weights(labels)
    assert weights is not None
    per_env = [found_loss(logits[:, [b]], labels[:, [b]], weights) for b in range(4)]
    p_found = torch.softmax(logits, dim=-1)[..., int(Action.FOUND)]
    positive = labels > 0.5
    balanced = (-torch.log(p_found[positive]).mean() - torch.log(1 - p_found[~positive]).mean()) / 2
    assert float(sum(per_env) / 4) == pytest.approx(float(balanced), rel=1e-5)


def test_a_gradient_step_raises_found_where_it_would_succeed_only() -> None:
    logits = torch.zeros(2, 4, requires_grad=True)
    labels = torch.tensor([1.0, 0.0])
    found_loss(logits, labels, (1.0, 1.0)).backward()
    assert logits.grad is not None
    stepped = torch.softmax(logits.detach() - 0.5 * logits.grad, dim=1)[:, int(Action.FOUND)]
    assert float(stepped[0]) > 0.25 > float(stepped[1])  # from 0.25 each


def test_the_log_says_how_likely_found_is_where_it_would_succeed() -> None:
    logits = torch.tensor([[2.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 3.0, 0.0]])
    p_found = torch.softmax(logits, dim=1)[:, int(Action.FOUND)]
    labels = torch.tensor([1.0, 0.0, 1.0]) > 0.5
    at_goal = mean_where(found_probabilities(logits, None), labels)
    assert at_goal is not None
    assert float(at_goal) == pytest.approx(float((p_found[0] + p_found[2]) / 2), rel=1e-6)
    elsewhere = mean_where(found_probabilities(logits, None), ~labels)
    assert elsewhere is not None and float(elsewhere) == pytest.approx(float(p_found[1]), rel=1e-6)
    assert mean_where(found_probabilities(logits, None), torch.zeros(3) > 0.5) is None


def test_only_training_receives_the_oracle(tmp_path: Path, room_dataset: Path) -> None:
    assert FOUND_LABEL_SENSOR not in run_env_config(tiny_args(tmp_path, room_dataset)).sensors
    args = tiny_args(tmp_path, room_dataset, frames=128, found_supervision=1.0)
    assert FOUND_LABEL_SENSOR in run_env_config(args).sensors
    train(args)
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert rows and all(0.0 <= float(row["found_positive_share"]) <= 1.0 for row in rows)
    for row in rows:  # the loss and P(FOUND) at the goal where an update had a step there
        at_goal = float(row["found_positive_share"]) > 0
        assert math.isfinite(float(row["found_loss"])) == at_goal, row
        assert math.isfinite(float(row["found_prob_at_goal"])) == at_goal, row
    policy, _, _ = load_policy(tmp_path / "run" / "checkpoint.pt")
    assert FOUND_LABEL_SENSOR not in policy.sensors  # the agent that acts never reads it
    resumed = dataclasses.replace(args, frames=256, resume=True, found_supervision=0.0)
    with pytest.raises(CheckpointError, match="--found-supervision"):
        train(resumed)


def test_the_option_is_bounded() -> None:
    with pytest.raises(ValueError, match=r"--found-supervision must be in \[0, 10\]"):
        Args(found_supervision=11.0)
