"""Issue 30: the faster learner learns what the one before it learned, and acting while the
simulators step plays the same rollouts.

The PPO loss of an oracle-map policy (the v3 recipe's model) and every gradient are compared
with the code before issue 30: the GRU's time loop as it was (kept below) and the cell
embedding applied before the map CNN instead of folded into its first convolution.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path
from typing import Any
from unittest import mock

import torch
from rollouts import actor_rollout, assert_same_loss_and_gradients, random_rollout, space_for
from torch import Tensor

from multion_agents.learned import policy as policy_module
from multion_agents.learned.encoders import MapCNN
from multion_agents.learned.env_groups import EnvGroups, make_env_groups
from multion_agents.learned.memory import Batch
from multion_agents.learned.models import MODELS, build_policy
from multion_agents.learned.oracle_maps import OracleMapMemory
from multion_agents.learned.ppo import Args, ppo_loss
from multion_agents.learned.rollout import Rollout, collect, start_episodes
from multion_agents.learned.rollout_envs import make_vector_env, training_env_config


class GRUBefore(torch.autograd.Function):
    """``MaskedGRU`` before issue 30 (lists of steps, stacked at the end)."""

    @staticmethod
    def forward(
        ctx: Any, gates_x: Tensor, h0: Tensor, keep: Tensor, w_hh: Tensor, b_hh: Tensor
    ) -> Tensor:
        hidden, outputs, saved = h0, [], []
        for t in range(gates_x.shape[0]):
            hidden = hidden * keep[t][:, None]
            x_r, x_z, x_n = gates_x[t].chunk(3, dim=1)
            h_r, h_z, h_n = torch.addmm(b_hh, hidden, w_hh.t()).chunk(3, dim=1)
            reset, update = torch.sigmoid(x_r + h_r), torch.sigmoid(x_z + h_z)
            candidate = torch.tanh(x_n + reset * h_n)
            saved.append((hidden, reset, update, candidate, h_n))
            hidden = (1.0 - update) * candidate + update * hidden
            outputs.append(hidden)
        ctx.save_for_backward(keep, w_hh, *(torch.stack(s) for s in zip(*saved, strict=True)))
        return torch.stack(outputs)

    @staticmethod
    def backward(ctx: Any, grad_outputs: Tensor) -> tuple[Tensor | None, ...]:
        keep, w_hh, previous, resets, updates, candidates, h_news = ctx.saved_tensors
        grad_x = grad_outputs.new_empty(*grad_outputs.shape[:2], 3 * grad_outputs.shape[2])
        grad_h_gates = torch.empty_like(grad_x)
        grad_next = torch.zeros_like(grad_outputs[0])
        for t in reversed(range(grad_outputs.shape[0])):
            grad_h = grad_outputs[t] + grad_next
            reset, update, candidate = resets[t], updates[t], candidates[t]
            grad_a_n = grad_h * (1.0 - update) * (1.0 - candidate * candidate)
            grad_a_z = grad_h * (previous[t] - candidate) * update * (1.0 - update)
            grad_a_r = grad_a_n * h_news[t] * reset * (1.0 - reset)
            grad_x[t] = torch.cat([grad_a_r, grad_a_z, grad_a_n], dim=1)
            grad_h_gates[t] = torch.cat([grad_a_r, grad_a_z, grad_a_n * reset], dim=1)
            grad_next = (grad_h * update + grad_h_gates[t] @ w_hh) * keep[t][:, None]
        flat = grad_h_gates.reshape(-1, grad_h_gates.shape[2])
        grad_w = flat.t() @ previous.reshape(-1, previous.shape[2])
        return grad_x, grad_next, None, grad_w, flat.sum(dim=0)


def embedding_before(self: OracleMapMemory, frames: Batch, image_features: Tensor | None) -> Batch:
    return {"map_embedding": self.cnn(self.embedding(frames[self.sensor].long()))}


def loss_and_gradients(before: bool) -> tuple[float, dict[str, Tensor]]:
    torch.manual_seed(0)
    config = training_env_config(
        1, ("rgb", "depth", "goal", "oracle_map"), 36, "val", {"maps": {"ego_size": 25}}
    )
    policy = build_policy("oracle-map", config)
    steps, envs = 24, 4
    generator = torch.Generator().manual_seed(1)
    cells = torch.stack(
        [
            torch.randint(0, 3, (steps, envs, 25, 25), generator=generator),
            torch.randint(0, 9, (steps, envs, 25, 25), generator=generator),
        ],
        dim=-1,
    ).to(torch.uint8)
    starts = torch.zeros(steps, envs)
    starts[0], starts[9, 1], starts[17, 3] = 1.0, 1.0, 1.0  # episodes start mid-rollout
    frames = {
        "rgb": torch.randint(0, 256, (steps, envs, 36, 36, 3), generator=generator).to(torch.uint8),
        "depth": torch.rand(steps, envs, 36, 36, 1, generator=generator),
        "goal": torch.randint(0, 8, (steps, envs), generator=generator),
        "oracle_map": cells,
    }
    rollout = actor_rollout(frames, starts, policy.initial_state(envs), generator)
    with (
        mock.patch.object(
            policy_module, "MaskedGRU", GRUBefore if before else policy_module.MaskedGRU
        ),
        mock.patch.object(
            OracleMapMemory,
            "precompute",
            embedding_before if before else OracleMapMemory.precompute,
        ),
    ):
        loss, _ = ppo_loss(policy, rollout, 0.2, Args())
        loss.backward()
    return float(loss), {
        n: p.grad.clone() for n, p in policy.named_parameters() if p.grad is not None
    }


def test_the_ppo_loss_and_its_gradients_are_those_of_the_code_before() -> None:
    loss, gradients = loss_and_gradients(before=False)
    loss_before, gradients_before = loss_and_gradients(before=True)
    assert_same_loss_and_gradients(loss, gradients, loss_before, gradients_before)
    assert "memory.embedding.category.weight" in gradients  # the folded tables still learn


def play(groups: EnvGroups, steps: int) -> Rollout:
    torch.manual_seed(0)
    config = training_env_config(1, ("rgb", "depth", "goal", "oracle_map"), 36, "val")
    policy = build_policy("oracle-map", config)
    torch.manual_seed(7)  # the actions' stream
    try:
        live = start_episodes(groups, policy, seed=11)
        rollout, _, _ = collect(groups, policy, live, steps, deque())
    finally:
        groups.close()
    return rollout


def test_two_groups_of_environments_play_the_rollout_of_one(room_dataset: Path) -> None:
    """Acting for one group while the other steps (issue 30) changes no action, frame or
    reward of a rollout: the environments are seeded, and the actions drawn, as before."""
    config = training_env_config(
        1, ("rgb", "depth", "goal", "oracle_map"), 36, "train", None, 12, str(room_dataset)
    )
    two = make_env_groups(config, 4)
    assert [g.num_envs for g in two.groups] == [2, 2]
    pipelined = play(two, 30)
    plain = play(EnvGroups([make_vector_env(config, 4)]), 30)
    assert plain.dones.sum() > 0  # episodes end inside the rollout (12-step limit)
    assert torch.equal(pipelined.actions, plain.actions)
    for key, frames in plain.frames.items():
        assert torch.equal(pipelined.frames[key], frames), key
    for name in ("rewards", "dones", "starts", "prev_actions", "expert_actions"):
        assert torch.equal(getattr(pipelined, name), getattr(plain, name)), name
    assert torch.allclose(pipelined.values, plain.values, atol=1e-5)
    assert torch.allclose(pipelined.logprobs, plain.logprobs, atol=1e-5)


def _loss_and_gradients(agent: str, rollout_seed: int) -> tuple[float, dict[str, Tensor]]:
    """PPO's loss and every gradient of a fresh ``agent`` on a random 6-step rollout of 2
    environments, its memory starting empty."""
    space = space_for(agent)
    rollout = random_rollout(space, seed=rollout_seed)
    torch.manual_seed(0)
    policy = MODELS[agent].build(space)
    rollout.initial_state = policy.initial_state(2)
    loss, _ = ppo_loss(policy, rollout, 0.2, Args())
    loss.backward()
    grads = {n: p.grad.clone() for n, p in policy.named_parameters() if p.grad is not None}
    return float(loss.detach()), grads


def test_channels_last_map_cnn_learns_what_the_contiguous_one_learned() -> None:
    """The map CNN's kernels and input in channels-last memory (faster on a CPU) compute the
    same function and gradients as in the default layout."""
    loss, grads = _loss_and_gradients("proj-neural-map", rollout_seed=4)
    assert grads["memory.cnn.net.0.weight"].abs().sum() > 0

    def contiguous(self: MapCNN, grid: Tensor) -> Tensor:
        for kernel in self.net.parameters():
            kernel.data = kernel.data.contiguous()
        out: Tensor = self.net(grid.contiguous())
        return out

    with mock.patch.object(MapCNN, "forward", contiguous):
        loss_before, grads_before = _loss_and_gradients("proj-neural-map", rollout_seed=4)
    assert grads_before["memory.cnn.net.0.weight"].is_contiguous()
    assert_same_loss_and_gradients(loss, grads, loss_before, grads_before)
