"""``--found-head`` (issue 51): a supervised head that alone decides FOUND. The gate, the replay
that gates as the acting did, the loss against hand computation, and the checkpoint that acts
with the head while never reading the oracle."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from rollouts import SIZE, sample_frames, space_for
from test_recipe_options import tiny_args

from multion.config.ranges import ConfigError
from multion.config.task import CameraConfig, EnvConfig
from multion_agents.learned.checkpoint import CheckpointError, load_checkpoint, load_policy
from multion_agents.learned.found_gate import FOUND_HEAD_PRIOR, gated_logits
from multion_agents.learned.found_supervision import (
    FOUND_LABEL_SENSOR,
    IN_VIEW_SENSOR,
    found_head_loss,
    found_label_sensors,
    found_probabilities,
    found_targets,
    goal_in_view,
)
from multion_agents.learned.models import build_policy, model_spec
from multion_agents.learned.policy import RecurrentPolicy
from multion_agents.learned.train_options import VisionPretraining
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_run import run_env_config, train
from multion_agents.learned.vision_frames import VisionFrames
from multion_agents.learned.vision_pretrain import FoundPretraining
from multion_client.constants import Action

FOUND = int(Action.FOUND)


def test_the_gate_calls_found_alone_or_only_moves() -> None:
    actor = torch.tensor([[1.0, 2.0, 0.5, 3.0], [1.0, 2.0, 0.5, 3.0]])
    probabilities = torch.softmax(gated_logits(actor, torch.tensor([True, False])), dim=-1)
    assert probabilities[0, FOUND] == 1.0
    assert probabilities[1, FOUND] == 0.0
    others = [a for a in range(4) if a != FOUND]
    moves = torch.softmax(actor[1, others], dim=0)  # the actor's own, FOUND left out
    assert probabilities[1, others].tolist() == pytest.approx(moves.tolist())


def _policy(seed: int = 0) -> tuple[RecurrentPolicy, dict[str, torch.Tensor]]:
    torch.manual_seed(seed)
    space = space_for("no-map")
    policy = model_spec("no-map").build(space, found_head=True)
    frames = {k: v for k, v in sample_frames(space, 5, 3, seed).items() if k in policy.sensors}
    return policy, frames


def _run(policy: RecurrentPolicy, frames: dict[str, torch.Tensor], actions: torch.Tensor | None):
    starts = torch.zeros(5, 3)
    starts[0] = 1
    previous = torch.zeros(5, 3, dtype=torch.long)
    state = policy.initial_state(3)
    if actions is None:
        return policy(frames, previous, starts, state)
    return policy.evaluate_actions(frames, previous, starts, state, actions)


def test_an_untrained_head_never_calls_found_and_an_open_one_always_does() -> None:
    policy, frames = _policy()
    assert policy.found_head is not None
    out = _run(policy, frames, None)
    assert out.found_logit is not None
    chances = found_probabilities(out.logits, out.found_logit)
    assert chances.detach() == pytest.approx(torch.full((15,), FOUND_HEAD_PRIOR), abs=0.01)
    assert float(torch.softmax(out.logits.detach(), -1)[..., FOUND].max()) == 0.0
    with torch.no_grad():
        policy.found_head.bias.fill_(5.0)
    assert torch.softmax(_run(policy, frames, None).logits, -1)[..., FOUND].min() == 1.0


def test_a_replay_gates_as_the_actions_were_taken_and_found_steps_teach_the_actor_nothing() -> None:
    policy, frames = _policy()
    move = [a for a in range(4) if a != FOUND]
    actions = torch.tensor(
        [[FOUND, move[0], move[1]], [move[2], FOUND, move[0]], [move[1], move[1], FOUND],
         [move[0], move[2], move[1]], [FOUND] * 3]
    )  # fmt: skip
    replay = _run(policy, frames, actions)  # the head is shut now; the FOUNDs were called
    fired = actions == FOUND
    assert replay.logprob[fired].tolist() == pytest.approx([0.0] * int(fired.sum()))
    assert replay.entropy[fired].tolist() == pytest.approx([0.0] * int(fired.sum()))
    actor = policy.actor  # the actor's own log-probabilities over the movements
    with torch.no_grad():
        logits = _run(policy, frames, None).logits  # gate shut: FOUND impossible
    moves = torch.log_softmax(logits[..., move], dim=-1)  # (T, B, 3)
    index = torch.tensor([[move.index(a) if a != FOUND else 0 for a in row] for row in actions])
    expected = moves.gather(-1, index[..., None])[..., 0]
    assert replay.logprob[~fired].tolist() == pytest.approx(expected[~fired].tolist(), abs=1e-5)
    replay.logprob[fired].sum().backward()  # PPO's ratio at a FOUND step is 1, whatever the actor
    assert actor.weight.grad is None or float(actor.weight.grad.abs().sum()) == 0.0


def test_the_loss_is_the_unweighted_binary_cross_entropy_computed_by_hand() -> None:
    logits = torch.tensor([2.0, -1.0, 0.5])
    labels = torch.tensor([1.0, 0.0, 0.0])
    p = torch.sigmoid(logits)
    expected = -(torch.log(p[0]) + torch.log(1 - p[1]) + torch.log(1 - p[2])) / 3
    assert float(found_head_loss(logits, labels)) == pytest.approx(float(expected), rel=1e-6)
    head = torch.zeros(2, requires_grad=True)
    found_head_loss(head, torch.tensor([1.0, 0.0])).backward()
    assert head.grad is not None and head.grad[0] < 0 < head.grad[1]  # up at the goal, down away


def test_weighted_positives_count_that_many_times_in_the_loss() -> None:
    logits = torch.tensor([2.0, -1.0, 0.5])
    labels = torch.tensor([1.0, 0.0, 0.0])
    p = torch.sigmoid(logits)
    expected = -(10 * torch.log(p[0]) + torch.log(1 - p[1]) + torch.log(1 - p[2])) / 3
    assert float(found_head_loss(logits, labels, 10.0)) == pytest.approx(float(expected), rel=1e-6)
    with pytest.raises(ValueError, match="--found-head-positive-weight .* needs --found-head"):
        Args(found_head_positive_weight=10.0)
    with pytest.raises(ValueError, match=r"--found-head-positive-weight must be in \[1, 1000\]"):
        Args(found_head=1.0, found_head_positive_weight=0.5)


def test_a_weighted_head_run_refuses_to_resume_unweighted(
    tmp_path: Path, room_dataset: Path
) -> None:
    args = tiny_args(tmp_path, room_dataset, found_head=1.0, frames=128)
    train(dataclasses.replace(args, found_head_positive_weight=10.0))
    recorded = load_checkpoint(tmp_path / "run" / "checkpoint.pt")["args"]
    assert recorded["found_head_positive_weight"] == 10.0
    with pytest.raises(CheckpointError, match="--found-head-positive-weight 10.0"):
        train(dataclasses.replace(args, frames=256, resume=True))


def test_the_heads_label_is_the_goal_within_reach_and_in_view() -> None:
    mask = torch.zeros(2, 2, 4, 4, dtype=torch.uint8)  # (T, B, H, W) goal_mask
    mask[0, 0, 1, 2] = 3  # category 2 shows
    mask[0, 1, 0, 0] = 5  # category 4 shows, but env 1's goal is 1
    mask[1, 0, 3, 3] = 3
    goal = torch.tensor([[2, 1], [2, 1]])
    assert goal_in_view(mask, goal).tolist() == [[True, False], [True, False]]
    distance = torch.tensor([[[1.0], [1.0]], [[2.0], [0.5]]])  # (T, B, 1)
    targets = found_targets(distance, 1.5, goal_in_view(mask, goal))
    assert targets.labels.tolist() == [[1.0, 0.0], [0.0, 0.0]]
    assert targets.weights is None  # the head's loss weighs every step alike
    supervision = found_targets(distance, 1.5)
    assert supervision.labels.tolist() == [[1.0, 1.0], [0.0, 1.0]]
    assert supervision.weights == (4 / 6, 4 / 2)  # found_supervision's balanced classes


def test_a_head_run_carries_both_label_sensors(tmp_path: Path, room_dataset: Path) -> None:
    args = tiny_args(tmp_path, room_dataset, found_head=1.0)
    assert found_label_sensors(args) == (FOUND_LABEL_SENSOR, IN_VIEW_SENSOR)
    assert found_label_sensors(tiny_args(tmp_path, room_dataset)) == ()
    sup = tiny_args(tmp_path, room_dataset, found_supervision=1.0)
    assert found_label_sensors(sup) == (FOUND_LABEL_SENSOR,)


def test_options_are_bounded_and_exclusive() -> None:
    with pytest.raises(ValueError, match=r"--found-head must be in \[0, 10\]"):
        Args(found_head=11.0)
    with pytest.raises(ConfigError, match="--found-head and --found-supervision"):
        Args(found_head=1.0, found_supervision=1.0)


def test_a_run_trains_the_head_and_its_checkpoint_acts_with_it(
    tmp_path: Path, room_dataset: Path
) -> None:
    args = tiny_args(tmp_path, room_dataset, frames=128, found_head=1.0)
    assert {FOUND_LABEL_SENSOR, IN_VIEW_SENSOR} <= set(run_env_config(args).sensors)
    train(args)
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert rows and all(math.isfinite(float(row["found_loss"])) for row in rows)
    assert all(0.0 < float(row["found_prob_elsewhere"]) < 1.0 for row in rows)
    path = tmp_path / "run" / "checkpoint.pt"
    assert "found_head.weight" in load_checkpoint(path)["model"]
    policy, _, _ = load_policy(path)
    assert policy.found_head is not None  # it decides FOUND: kept to act
    assert FOUND_LABEL_SENSOR not in policy.sensors and IN_VIEW_SENSOR not in policy.sensors
    with pytest.raises(CheckpointError, match="--found-head"):
        train(dataclasses.replace(args, frames=256, resume=True, found_head=0.0))


def test_vision_pretraining_labels_the_head_within_the_success_distance() -> None:
    policy, _ = _policy()
    frames = VisionFrames(
        rgb=np.zeros((4, SIZE, SIZE, 3), dtype=np.uint8),
        depth=np.zeros((4, SIZE, SIZE, 1), dtype=np.float32),
        labels=np.zeros((4, 8), dtype=np.int64),
        goal=np.array([0, 3, 5, 2]),
        distance=np.array([0.4, 1.5, 1.6, 1.0], dtype=np.float32),
        recognition=np.zeros(4, dtype=np.int64),
    )
    frames.labels[[0, 1, 2], [0, 3, 5]] = [2, 1, 3]  # goals 0, 3, 5 show; goal 2 does not
    frames.labels[3, 4] = 2  # frame 3 shows another category
    config = EnvConfig(sensors=policy.sensors, camera=CameraConfig(width=SIZE, height=SIZE))
    found = FoundPretraining.of(policy, config)
    assert found is not None and found.success_distance == config.task.success_distance == 1.5
    index = np.arange(4)
    assert found.labels(frames, index).tolist() == [1.0, 1.0, 0.0, 0.0]  # near and in view
    assert found.logits(frames, index).shape == (4,)
    without, _ = _policy()
    without.found_head = None
    assert FoundPretraining.of(without, config) is None


def test_vision_pretraining_trains_the_head_before_ppo(tmp_path: Path, room_dataset: Path) -> None:
    vision = VisionPretraining(steps=100, samples=200, held_out=100, max_distance=4.0)
    args = tiny_args(tmp_path, room_dataset, frames=64, found_head=1.0, pretrain_vision=vision)
    train(args)
    rows = list(csv.DictReader((tmp_path / "run" / "pretrain_vision.csv").open()))
    assert rows and all(0.0 < float(row["found_near"]) < 1.0 for row in rows)
    assert all(0.0 < float(row["found_far"]) < 1.0 for row in rows)
    untrained = build_policy("no-map", run_env_config(args), found_head=True)
    weights = load_checkpoint(tmp_path / "run" / "checkpoint.pt")["model"]
    assert untrained.found_head is not None
    assert not torch.equal(weights["found_head.bias"], untrained.found_head.bias.detach())


@pytest.mark.parametrize("agent", ["proj-neural-map", "obj-recog-map", "oracle-ego-map"])
def test_every_agent_with_a_map_pretrains_its_head_from_blank_readings(agent: str) -> None:
    space = space_for(agent)
    policy = model_spec(agent).build(space, found_head=True)
    config = EnvConfig(sensors=policy.sensors, camera=CameraConfig(width=SIZE, height=SIZE))
    found = FoundPretraining.of(policy, config)
    assert found is not None and set(found.blank) == set(policy.sensors) - {"rgb", "depth", "goal"}
    frames = VisionFrames(
        rgb=np.zeros((2, SIZE, SIZE, 3), dtype=np.uint8),
        depth=np.zeros((2, SIZE, SIZE, 1), dtype=np.float32),
        labels=np.zeros((2, 8), dtype=np.int64),
        goal=np.array([0, 3]),
        distance=np.array([0.4, 3.0], dtype=np.float32),
        recognition=np.zeros(2, dtype=np.int64),
    )
    assert torch.isfinite(found.logits(frames, np.arange(2))).all()
