"""Device safety without a GPU: every model, memory, the GRU and the PPO loss run on torch's
``meta`` device, where any tensor created on the CPU by mistake raises ("Tensor on device cpu
is not on the expected device meta"). What passes here runs on ``--device cuda``."""

from __future__ import annotations

import pytest
import torch

from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig
from multion.task.spaces import build_observation_space
from multion_agents.learned.gru import MaskedGRU
from multion_agents.learned.models import MODELS
from multion_agents.learned.ppo import Args, ppo_loss
from multion_agents.learned.rollout import Rollout, compute_gae

META = torch.device("meta")
SIZE = 48


def space_for(name: str):
    config = EnvConfig(
        sensors=MODELS[name].train_sensors, camera=CameraConfig(width=SIZE, height=SIZE)
    )
    return build_observation_space(config)


def sample_frames(space, steps: int, batch: int) -> dict[str, torch.Tensor]:
    space.seed(0)
    return {
        k: torch.stack(
            [torch.stack([torch.as_tensor(space[k].sample()) for _ in range(batch)])] * steps
        )
        for k in space.spaces
    }


@pytest.fixture(autouse=True)
def no_distribution_validation():
    """Distribution argument checks read a value on the host, which meta tensors lack."""
    previous = torch.distributions.Distribution._validate_args
    torch.distributions.Distribution.set_default_validate_args(False)
    yield
    torch.distributions.Distribution.set_default_validate_args(previous)


def test_a_cpu_tensor_mixed_into_meta_work_raises() -> None:
    """The premise of these tests: meta does not silently accept CPU tensors."""
    with pytest.raises(RuntimeError, match="device"):
        _ = torch.zeros(3, device=META) + torch.zeros(3)


def test_masked_gru_backward_stays_on_the_input_device() -> None:
    steps, batch, hidden = 4, 2, 3
    gates = torch.zeros(steps, batch, 3 * hidden, device=META, requires_grad=True)
    h0 = torch.zeros(batch, hidden, device=META, requires_grad=True)
    w_hh = torch.zeros(3 * hidden, hidden, device=META, requires_grad=True)
    b_hh = torch.zeros(3 * hidden, device=META, requires_grad=True)
    keep = torch.ones(steps, batch, device=META)
    outputs = MaskedGRU.apply(gates, h0, keep, w_hh, b_hh)
    outputs.sum().backward()
    for tensor in (gates, h0, w_hh, b_hh):
        assert tensor.grad is not None and tensor.grad.device == META


@pytest.mark.parametrize("name", list(MODELS))
def test_every_model_and_the_ppo_loss_follow_the_device(name: str) -> None:
    space = space_for(name)
    policy = MODELS[name].build(space).to(META)
    steps, batch = 3, 2
    state = policy.initial_state(batch)
    assert state and all(v.device == META for v in state.values()), "initial state off device"
    frames = {k: v.to(META) for k, v in sample_frames(space, steps, batch).items()}
    actions = torch.zeros(steps, batch, dtype=torch.long, device=META)
    starts = torch.zeros(steps, batch, device=META)
    rollout = Rollout(
        frames=frames,
        prev_actions=actions,
        starts=starts,
        actions=actions,
        logprobs=torch.zeros(steps, batch, device=META),
        values=torch.zeros(steps, batch, device=META),
        rewards=torch.zeros(steps, batch, device=META),
        dones=torch.zeros(steps, batch, device=META),
        initial_state=state,
    )
    compute_gae(rollout, torch.zeros(batch, device=META), 0.99, 0.95)
    loss, terms = ppo_loss(policy, rollout, 0.2, Args())
    assert loss.device == META
    assert all(t is None or t.device == META for t in terms.values())
    loss.backward()
    grads = [p.grad for p in policy.parameters() if p.grad is not None]
    assert grads and all(g.device == META for g in grads)
    out = policy.step({k: v[0] for k, v in frames.items()}, actions[0], starts[0] + 1.0, state)
    assert out.logits.device == META
    assert all(v.device == META for v in out.state.values()), "new state off device"
