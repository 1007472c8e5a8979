"""``--pose-input`` (issue 51): the GRU also reads GPS and compass, embedded as in habitat-lab's
ObjectNav baseline. Without it nothing changes; with it the pose reaches the GRU and nothing
else, the compass is read as an angle, and a checkpoint acts with it and resumes only with it."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import torch
from rollouts import SIZE, sample_frames
from test_recipe_options import assert_resumes_only_with, tiny_args

from multion.config.task import CameraConfig, EnvConfig
from multion.task.spaces import build_observation_space
from multion_agents.learned.checkpoint import load_checkpoint, load_policy
from multion_agents.learned.models import MODELS
from multion_agents.learned.policy import POSE_EMBED_DIM, POSE_SENSORS, RecurrentPolicy
from multion_agents.learned.training_run import run_env_config, train


def _space(name: str):
    sensors = tuple(dict.fromkeys(MODELS[name].train_sensors + POSE_SENSORS))
    return build_observation_space(
        EnvConfig(sensors=sensors, camera=CameraConfig(width=SIZE, height=SIZE))
    )


def _policy(name: str, pose_input: bool, seed: int = 0) -> RecurrentPolicy:
    torch.manual_seed(seed)
    return MODELS[name].build(_space(name), pose_input=pose_input)


def _logits(policy: RecurrentPolicy, frames: dict[str, torch.Tensor]) -> torch.Tensor:
    steps, batch = frames["goal"].shape[:2]
    starts = torch.zeros(steps, batch)
    starts[0] = 1
    previous = torch.zeros(steps, batch, dtype=torch.long)
    inputs = {k: v for k, v in frames.items() if k in policy.train_sensors}
    with torch.no_grad():
        return policy(inputs, previous, starts, policy.initial_state(batch)).logits


def test_without_the_option_the_policy_reads_no_pose() -> None:
    plain, posed = _policy("no-map", False), _policy("no-map", True)
    assert not set(POSE_SENSORS) & set(plain.sensors)
    assert set(POSE_SENSORS) <= set(posed.sensors)
    assert plain.gps_embedding is None and not plain.pose_input
    assert posed.gru.input_size == plain.gru.input_size + 2 * POSE_EMBED_DIM


def test_the_pose_reaches_the_gru_and_only_through_its_new_columns() -> None:
    plain, posed = _policy("no-map", False), _policy("no-map", True)
    frames = sample_frames(_space("no-map"), 4, 3, seed=1)
    moved = {**frames, "gps": frames["gps"] + 1.5}
    assert not torch.allclose(_logits(posed, frames), _logits(posed, moved))
    assert torch.equal(_logits(plain, frames), _logits(plain, moved))  # it does not read gps
    # the posed policy with the plain one's weights and its pose columns zeroed acts as it
    weights = plain.state_dict()
    query = plain.query_dim
    columns = posed.gru.weight_ih_l0.detach().clone()
    columns[:, :query] = weights["gru.weight_ih_l0"]
    columns[:, query:] = 0.0
    posed.load_state_dict({**posed.state_dict(), **weights, "gru.weight_ih_l0": columns})
    assert torch.allclose(_logits(posed, frames), _logits(plain, frames), atol=1e-6)


def test_the_compass_is_read_as_an_angle() -> None:
    policy = _policy("no-map", True)
    frames = sample_frames(_space("no-map"), 3, 2, seed=2)
    at = {
        heading: {**frames, "compass": torch.full_like(frames["compass"], heading)}
        for heading in (math.pi, -math.pi, 0.0)
    }
    assert torch.allclose(_logits(policy, at[math.pi]), _logits(policy, at[-math.pi]), atol=1e-5)
    assert not torch.allclose(_logits(policy, at[math.pi]), _logits(policy, at[0.0]))


@pytest.mark.parametrize("name", ["oracle-map", "frmqn", "proj-neural-map"])
def test_agents_with_a_memory_take_the_pose_beside_it(name: str) -> None:
    plain, posed = _policy(name, False), _policy(name, True)
    assert posed.gru.input_size == plain.gru.input_size + 2 * POSE_EMBED_DIM
    frames = sample_frames(_space(name), 3, 2, seed=3)
    assert _logits(posed, frames).shape == _logits(plain, frames).shape == (3, 2, 4)


def test_a_pose_run_acts_with_the_pose_and_resumes_only_with_it(
    tmp_path: Path, room_dataset: Path
) -> None:
    assert not set(POSE_SENSORS) & set(run_env_config(tiny_args(tmp_path, room_dataset)).sensors)
    args = tiny_args(tmp_path, room_dataset, frames=128, pose_input=True)
    assert set(POSE_SENSORS) <= set(run_env_config(args).sensors)
    train(args)
    path = tmp_path / "run" / "checkpoint.pt"
    payload = load_checkpoint(path)
    assert payload["args"]["pose_input"] is True
    assert "gps_embedding.weight" in payload["model"]
    policy, _, model = load_policy(path)
    assert model == "no-map" and policy.pose_input
    assert set(POSE_SENSORS) <= set(policy.sensors)
    assert_resumes_only_with(args, "pose_input")
