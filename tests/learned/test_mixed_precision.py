"""Mixed precision for the PPO update (issue 44 item 2): one update's losses under bf16
autocast (on the CPU, which torch supports) stay close to float32's."""

from __future__ import annotations

import pytest
import torch
from rollouts import random_rollout, space_for

from multion_agents.learned.models import build_policy, model_spec
from multion_agents.learned.ppo import ppo_update
from multion_agents.learned.precision import update_precision
from multion_agents.learned.rollout_envs import training_env_config
from multion_agents.learned.train_settings import Args

TOLERANCE = 0.01
"""Relative difference of each logged loss, bf16 vs float32. Measured on one update of 8 steps
× 4 envs of random 64² frames: at most 0.43% (the policy loss; the value and auxiliary losses
within 0.002%), for no-map, oracle-map, obj-recog-map and proj-neural-map."""


def one_update(agent: str, mode: str) -> dict[str, float]:
    spec = model_spec(agent)
    config = training_env_config(1, spec.train_sensors, 64, "train", spec.config_overrides)
    torch.manual_seed(0)
    policy = build_policy(agent, config)
    optimizer = torch.optim.Adam(policy.parameters(), lr=2.5e-4, eps=1e-5)
    rollout = random_rollout(space_for(agent), seed=3, steps=8, envs=4)
    rollout.initial_state = {k: v.clone() for k, v in policy.initial_state(4).items()}
    torch.manual_seed(1)
    args = Args(agent=agent, mixed_precision=mode, epochs=1, minibatches=1)
    return ppo_update(policy, optimizer, rollout, args)


@pytest.mark.parametrize("agent", ["no-map", "proj-neural-map"])
def test_bf16_losses_are_within_the_tolerance_of_float32(agent: str) -> None:
    exact, mixed = one_update(agent, "off"), one_update(agent, "bf16")
    assert mixed["policy_loss"] != exact["policy_loss"]  # autocast did run in bf16
    for name in ("policy_loss", "value_loss", "entropy", "grad_norm"):
        assert mixed[name] == pytest.approx(exact[name], rel=TOLERANCE), name


def test_fp16_needs_cuda_and_unknown_modes_are_refused() -> None:
    optimizer = torch.optim.SGD([torch.zeros(1, requires_grad=True)], lr=0.1)
    with pytest.raises(ValueError, match="fp16 needs a CUDA device"):
        update_precision("fp16", torch.device("cpu"), optimizer)
    with pytest.raises(ValueError, match="mixed.precision"):
        Args(mixed_precision="fp8")
