"""``--separate-critic`` (issue 51): the critic reads its own GRU over the actor GRU's inputs,
detached. Without it nothing changes; with it the value loss trains only the critic's GRU and
head, the actor acts as before, and a checkpoint acts without the critic's GRU and resumes only
with the option it was trained with."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from rollouts import SIZE, sample_frames
from test_recipe_options import assert_resumes_only_with, tiny_args

from multion.config.task import CameraConfig, EnvConfig
from multion.task.spaces import build_observation_space
from multion_agents.learned.checkpoint import load_checkpoint, load_policy
from multion_agents.learned.models import MODELS
from multion_agents.learned.policy import PolicyOutput, RecurrentPolicy
from multion_agents.learned.training_run import train


def _space(name: str):
    return build_observation_space(
        EnvConfig(sensors=MODELS[name].train_sensors, camera=CameraConfig(width=SIZE, height=SIZE))
    )


def _policy(name: str, separate_critic: bool, seed: int = 0) -> RecurrentPolicy:
    torch.manual_seed(seed)
    return MODELS[name].build(_space(name), separate_critic=separate_critic)


def _run(policy: RecurrentPolicy, frames: dict[str, torch.Tensor]) -> PolicyOutput:
    steps, batch = frames["goal"].shape[:2]
    starts = torch.zeros(steps, batch)
    starts[0] = 1
    starts[2, 0] = 1  # a new episode mid-sequence clears both GRUs' states
    previous = torch.zeros(steps, batch, dtype=torch.long)
    inputs = {k: v for k, v in frames.items() if k in policy.train_sensors}
    output: PolicyOutput = policy(inputs, previous, starts, policy.initial_state(batch))
    return output


def _gradient_norms(policy: RecurrentPolicy, loss: torch.Tensor) -> dict[str, float]:
    """The gradient norm of ``loss`` on each top-level module's weights (0: none reached it)."""
    policy.zero_grad()
    loss.backward()
    norms: dict[str, float] = {}
    for name, parameter in policy.named_parameters():
        module = name.split(".")[0]
        grad = 0.0 if parameter.grad is None else float(parameter.grad.norm())
        norms[module] = norms.get(module, 0.0) + grad
    return norms


def test_without_the_option_the_critic_shares_the_actors_gru() -> None:
    plain, separate = _policy("no-map", False), _policy("no-map", True)
    assert plain.critic_gru is None and not plain.separate_critic
    assert set(plain.initial_state(2)) == {"hidden"}
    assert separate.separate_critic
    assert set(separate.initial_state(2)) == {"hidden", "critic_hidden"}
    assert separate.critic_gru is not None
    assert separate.critic_gru.input_size == separate.gru.input_size
    frames = sample_frames(_space("no-map"), 4, 3, seed=1)
    norms = _gradient_norms(plain, _run(plain, frames).value.square().mean())
    assert norms["gru"] > 0 and norms["image_encoder"] > 0  # the shared trunk hears the critic


def test_the_value_loss_trains_only_the_critics_own_gru_and_head() -> None:
    policy = _policy("no-map", True)
    frames = sample_frames(_space("no-map"), 4, 3, seed=1)
    value = _gradient_norms(policy, _run(policy, frames).value.square().mean())
    assert value["critic_gru"] > 0 and value["critic"] > 0
    for trunk in ("gru", "image_encoder", "goal_embedding", "action_embedding", "actor"):
        assert value[trunk] == 0.0, trunk
    actor = _gradient_norms(policy, _run(policy, frames).logits.logsumexp(-1).mean())
    assert actor["gru"] > 0 and actor["image_encoder"] > 0
    assert actor["critic_gru"] == 0.0 and actor["critic"] == 0.0


def test_the_actor_acts_as_without_the_option() -> None:
    plain, separate = _policy("no-map", False), _policy("no-map", True)
    shared = plain.state_dict()
    separate.load_state_dict({**separate.state_dict(), **shared})
    frames = sample_frames(_space("no-map"), 5, 2, seed=2)
    with torch.no_grad():
        ours, theirs = _run(separate, frames), _run(plain, frames)
    assert torch.allclose(ours.logits, theirs.logits, atol=1e-6)
    assert torch.allclose(ours.state["hidden"], theirs.state["hidden"], atol=1e-6)
    assert not torch.allclose(ours.value, theirs.value)  # the critic reads another GRU


@pytest.mark.parametrize("name", ["oracle-map", "frmqn", "proj-neural-map"])
def test_agents_with_a_memory_give_the_critic_the_memory_too(name: str) -> None:
    policy = _policy(name, True)
    frames = sample_frames(_space(name), 3, 2, seed=3)
    output = _run(policy, frames)
    assert output.value.shape == (3, 2) and output.logits.shape == (3, 2, 4)
    assert output.state["critic_hidden"].shape == output.state["hidden"].shape
    assert not torch.allclose(output.state["critic_hidden"], output.state["hidden"])
    value = _gradient_norms(policy, output.value.square().mean())
    assert value["critic_gru"] > 0 and value["gru"] == 0.0 and value["memory"] == 0.0


def test_a_separate_critic_run_acts_without_it_and_resumes_only_with_it(
    tmp_path: Path, room_dataset: Path
) -> None:
    args = tiny_args(tmp_path, room_dataset, frames=128, separate_critic=True)
    train(args)
    path = tmp_path / "run" / "checkpoint.pt"
    payload = load_checkpoint(path)
    assert payload["args"]["separate_critic"] is True
    assert "critic_gru.weight_hh_l0" in payload["model"]
    policy, _, model = load_policy(path)
    assert model == "no-map" and not policy.separate_critic
    assert torch.equal(policy.gru.weight_hh_l0, payload["model"]["gru.weight_hh_l0"])
    assert_resumes_only_with(args, "separate_critic")
