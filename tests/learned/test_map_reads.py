"""Issue 30: the learned-map agents read all of a replay's map crops in one batch
(:class:`~multion_agents.learned.memory.MapMemory`), and learn what they learned when each
step's crop was read on its own.

"Before" is the same code with the batched read switched off: the policy then calls the
memory's ``step`` (update, then read) at every time step, as it did before the split.
"""

from __future__ import annotations

from unittest import mock

import pytest
import torch
from rollouts import actor_rollout, assert_same_loss_and_gradients
from torch import Tensor

from multion_agents.learned import policy as policy_module
from multion_agents.learned.memory import MapMemory
from multion_agents.learned.models import build_policy, model_spec
from multion_agents.learned.ppo import Args, ppo_loss
from multion_agents.learned.rollout_envs import training_env_config


class NotAMapMemory:
    """Stands in for ``MapMemory`` in the policy's ``isinstance`` test: no memory is one."""


def replay(agent: str, batched: bool) -> tuple[Tensor, float, dict[str, Tensor], int]:
    """Logits, PPO loss and every gradient of a fresh ``agent`` policy on a fixed random
    rollout of 12 steps × 3 environments, with episodes starting mid-rollout; and how many
    times the map CNN ran (two replays: the logits' and the loss's)."""
    torch.manual_seed(0)
    config = training_env_config(1, model_spec(agent).train_sensors, 36, "val")
    policy = build_policy(agent, config)
    assert isinstance(policy.memory, MapMemory)
    steps, envs = 12, 3
    generator = torch.Generator().manual_seed(1)
    # a random walk of poses, so the maps fill over several cells
    gps = torch.cumsum(torch.randn(steps, envs, 2, generator=generator) * 0.5, dim=0)
    compass = torch.rand(steps, envs, 1, generator=generator) * 6.28 - 3.14
    frames = {
        "rgb": torch.randint(0, 256, (steps, envs, 36, 36, 3), generator=generator).to(torch.uint8),
        "depth": torch.rand(steps, envs, 36, 36, 1, generator=generator),
        "goal": torch.randint(0, 8, (steps, envs), generator=generator),
        "gps": gps,
        "compass": compass,
        "goal_mask": torch.randint(0, 9, (steps, envs, 36, 36), generator=generator).to(
            torch.uint8
        ),
    }
    starts = torch.zeros(steps, envs)
    starts[0], starts[5, 1], starts[8, 2] = 1.0, 1.0, 1.0
    kept = {k: frames[k] for k in policy.train_sensors}
    rollout = actor_rollout(kept, starts, policy.initial_state(envs), generator)
    calls = []
    policy.memory.get_submodule("cnn").register_forward_hook(lambda *_: calls.append(1))
    switch = policy_module.MapMemory if batched else NotAMapMemory
    with mock.patch.object(policy_module, "MapMemory", switch):
        out = policy(rollout.frames, rollout.prev_actions, rollout.starts, rollout.initial_state)
        loss, _ = ppo_loss(policy, rollout, 0.2, Args())
        loss.backward()
    gradients = {n: p.grad.clone() for n, p in policy.named_parameters() if p.grad is not None}
    return out.logits.detach(), float(loss), gradients, len(calls)


@pytest.mark.parametrize("agent", ["proj-neural-map", "obj-recog-map", "dynamic-obj-recog-map"])
def test_batched_map_reads_give_the_step_by_step_outputs_and_gradients(agent: str) -> None:
    logits, loss, gradients, reads = replay(agent, batched=True)
    logits_before, loss_before, gradients_before, reads_before = replay(agent, batched=False)
    assert (reads, reads_before) == (2, 2 * 12)  # one batched read per replay, against T
    torch.testing.assert_close(logits, logits_before, rtol=1e-4, atol=1e-5)
    assert_same_loss_and_gradients(loss, gradients, loss_before, gradients_before)
    # the map's reader learns (its gradient is not zero), so the comparison is not vacuous
    reader = [n for n in gradients if n.startswith("memory.cnn.")]
    assert reader and all(float(gradients[n].abs().max()) > 0 for n in reader)


def test_acting_one_step_equals_the_memory_step() -> None:
    """The acting path (T = 1, batched read of one view) is the memory's own ``step``."""
    torch.manual_seed(0)
    config = training_env_config(1, model_spec("proj-neural-map").train_sensors, 36, "val")
    policy = build_policy("proj-neural-map", config)
    memory = policy.memory
    assert isinstance(memory, MapMemory)
    generator = torch.Generator().manual_seed(2)
    frame = {
        "depth": torch.rand(2, 36, 36, 1, generator=generator),
        "gps": torch.randn(2, 2, generator=generator),
        "compass": torch.rand(2, 1, generator=generator),
    }
    features = torch.rand(2, 32, 9, 9, generator=generator)
    precomputed = memory.precompute(frame, features)
    state = memory.initial_state(2, torch.device("cpu"))
    with torch.no_grad():
        v_m, after = memory.step({**frame, **precomputed}, torch.empty(2, 0), state)
        view, after_advance = memory.advance({**frame, **precomputed}, state)
        torch.testing.assert_close(memory.read(view, frame), v_m)
    torch.testing.assert_close(after["map"], after_advance["map"])
    assert float(after["map"].abs().sum()) > 0  # the step wrote something
