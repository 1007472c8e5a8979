"""Collecting PPO's rollouts: ``T`` steps of ``E`` environments with the policy in control.

:func:`start_episodes` resets the environments into a :class:`Live` (what carries over from one
rollout to the next), :func:`collect` plays one rollout from it, and :func:`compute_gae` adds
advantages and returns. The update itself is in :mod:`.ppo`.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from gymnasium.vector import VectorEnv
from torch import Tensor

from multion_agents.learned.policy import RecurrentPolicy, State, frames_to_tensors
from multion_agents.learned.rollout_envs import expert_labels, finished_episodes


@dataclass
class Rollout:
    """``T`` steps of ``E`` environments, everything (T, E, ...) except the initial state."""

    frames: dict[str, Tensor]
    prev_actions: Tensor
    starts: Tensor
    actions: Tensor
    logprobs: Tensor
    values: Tensor
    rewards: Tensor
    dones: Tensor
    initial_state: State
    advantages: Tensor = field(default_factory=lambda: torch.empty(0))
    returns: Tensor = field(default_factory=lambda: torch.empty(0))
    expert_actions: Tensor = field(default_factory=lambda: torch.empty(0, dtype=torch.long))
    """The expert's action for each frame (``NO_LABEL`` where none); empty: no labels at all."""


@dataclass
class Live:
    """The environments' state between rollouts: current observations and their expert labels,
    the policy's memories, previous actions, episode-start flags and running returns."""

    observation: dict[str, Any]
    labels: np.ndarray
    state: State
    prev_action: Tensor
    start: Tensor
    returns: np.ndarray


@dataclass
class Timing:
    sim_seconds: float = 0.0
    act_seconds: float = 0.0


def start_episodes(envs: VectorEnv, policy: RecurrentPolicy, seed: int) -> Live:
    """Reset every environment (seeded with ``seed``) and start empty memories."""
    observation, infos = envs.reset(seed=seed)
    count = envs.num_envs
    return Live(
        observation=observation,
        labels=expert_labels(infos, count),
        state=policy.initial_state(count),
        prev_action=torch.zeros(count, dtype=torch.long),
        start=torch.ones(count),
        returns=np.zeros(count),
    )


def collect(
    envs: VectorEnv,
    policy: RecurrentPolicy,
    live: Live,
    steps: int,
    finished: deque[dict[str, float]],
) -> tuple[Rollout, Tensor, Timing]:
    """Play ``steps`` steps from ``live`` (updated in place) with actions sampled from
    ``policy``; the summary metrics and return of every episode that ends are appended to
    ``finished``. Returns the rollout (its expert labels all ``NO_LABEL`` when the environments
    give none), the value of the observation after it, and timings."""
    device, keys, count = policy.device, policy.train_sensors, envs.num_envs
    timing = Timing()
    initial_state = {k: v.detach().cpu().clone() for k, v in live.state.items()}
    columns: dict[str, list[Tensor]] = {
        k: [] for k in ("prev", "start", "action", "logprob", "value", "reward", "done", "label")
    }
    stored: dict[str, list[Tensor]] = {k: [] for k in keys}
    for _ in range(steps):
        frame = frames_to_tensors(live.observation, keys)
        for k in keys:
            stored[k].append(frame[k])
        tick = time.perf_counter()
        with torch.no_grad():
            action, logprob, value, live.state = policy.get_action_and_value(
                {k: v.to(device) for k, v in frame.items()},
                live.prev_action.to(device),
                live.start.to(device),
                live.state,
            )
        timing.act_seconds += time.perf_counter() - tick
        tick = time.perf_counter()
        live.observation, reward, terminated, truncated, infos = envs.step(action.cpu().numpy())
        timing.sim_seconds += time.perf_counter() - tick
        done = np.logical_or(terminated, truncated)
        live.returns += reward
        for index, metrics in finished_episodes(infos):
            finished.append({**metrics, "return": float(live.returns[index])})
            live.returns[index] = 0.0
        for key, item in (
            ("label", torch.as_tensor(live.labels)),  # the label of the frame acted on
            ("prev", live.prev_action),
            ("start", live.start),
            ("action", action.cpu()),
            ("logprob", logprob.cpu()),
            ("value", value.cpu()),
            ("reward", torch.as_tensor(reward, dtype=torch.float32)),
            ("done", torch.as_tensor(done, dtype=torch.float32)),
        ):
            columns[key].append(item)
        live.prev_action = action.cpu()
        live.start = torch.as_tensor(done, dtype=torch.float32)
        live.labels = expert_labels(infos, count)
    with torch.no_grad():
        frame = frames_to_tensors(live.observation, keys)
        next_value = policy.get_value(
            {k: v.to(device) for k, v in frame.items()},
            live.prev_action.to(device),
            live.start.to(device),
            live.state,
        ).cpu()
    rollout = Rollout(
        frames={k: torch.stack(v) for k, v in stored.items()},
        prev_actions=torch.stack(columns["prev"]),
        starts=torch.stack(columns["start"]),
        actions=torch.stack(columns["action"]),
        logprobs=torch.stack(columns["logprob"]),
        values=torch.stack(columns["value"]),
        rewards=torch.stack(columns["reward"]),
        dones=torch.stack(columns["done"]),
        initial_state=initial_state,
        expert_actions=torch.stack(columns["label"]),
    )
    return rollout, next_value, timing


def compute_gae(rollout: Rollout, next_value: Tensor, gamma: float, lam: float) -> None:
    """Generalised advantage estimation; ``dones[t]`` ends the episode after step t."""
    steps = rollout.rewards.shape[0]
    advantages = torch.zeros_like(rollout.rewards)
    last = torch.zeros_like(next_value)
    for t in reversed(range(steps)):
        following = next_value if t == steps - 1 else rollout.values[t + 1]
        alive = 1.0 - rollout.dones[t]
        delta = rollout.rewards[t] + gamma * following * alive - rollout.values[t]
        last = delta + gamma * lam * alive * last
        advantages[t] = last
    rollout.advantages = advantages
    rollout.returns = advantages + rollout.values
