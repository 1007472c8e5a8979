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
from torch import Tensor

from multion_agents.learned.env_groups import EnvGroups, StepResult
from multion_agents.learned.memory import State
from multion_agents.learned.policy import RecurrentPolicy, frames_to_tensors
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


def start_episodes(envs: EnvGroups, policy: RecurrentPolicy, seed: int) -> Live:
    """Reset every environment (seeded with ``seed``) and start empty memories."""
    observation, infos = envs.reset(seed)
    count = envs.num_envs
    labels = np.concatenate(
        [
            expert_labels(info, rows.stop - rows.start)
            for info, rows in zip(infos, envs.rows, strict=True)
        ]
    )
    return Live(
        observation=observation,
        labels=labels,
        state=policy.initial_state(count),
        prev_action=torch.zeros(count, dtype=torch.long),
        start=torch.ones(count),
        returns=np.zeros(count),
    )


def collect(
    envs: EnvGroups,
    policy: RecurrentPolicy,
    live: Live,
    steps: int,
    finished: deque[dict[str, float]],
    labels: tuple[str, ...] = (),
) -> tuple[Rollout, Tensor, Timing]:
    """Play ``steps`` steps from ``live`` (updated in place) with actions sampled from
    ``policy``; the summary metrics and return of every episode that ends are appended to
    ``finished``. Returns the rollout (its expert labels all ``NO_LABEL`` when the environments
    give none), the value of the observation after it, and timings.

    The groups take turns (:mod:`.env_groups`): the policy acts for a group while the others
    step, so ``sim_seconds`` is only the time spent waiting for them. ``labels``: sensors kept
    in the rollout for the loss beside the policy's own (``--found-supervision``'s oracle)."""
    keys, count = tuple(dict.fromkeys(policy.train_sensors + labels)), envs.num_envs
    timing = Timing()
    initial_state = {k: v.detach().cpu().clone() for k, v in live.state.items()}
    columns = {
        "label": torch.empty(steps, count, dtype=torch.long),
        "prev": torch.empty(steps, count, dtype=torch.long),
        "start": torch.empty(steps, count),
        "action": torch.empty(steps, count, dtype=torch.long),
        "logprob": torch.empty(steps, count),
        "value": torch.empty(steps, count),
        "reward": torch.empty(steps, count),
        "done": torch.empty(steps, count),
    }
    frames = {
        k: torch.empty(steps, *np.shape(live.observation[k]), dtype=_dtype(live.observation[k]))
        for k in keys
    }
    for t in range(steps + 1):
        for index, rows in enumerate(envs.rows):
            if t > 0:  # the group's previous step
                tick = time.perf_counter()
                result = envs.finish_step(index)
                timing.sim_seconds += time.perf_counter() - tick
                _record_step(live, columns, t - 1, rows, result, finished)
            if t < steps:
                tick = time.perf_counter()
                action = _act(policy, live, frames, columns, t, rows, keys)
                timing.act_seconds += time.perf_counter() - tick
                tick = time.perf_counter()
                envs.start_step(index, action.numpy())
                timing.sim_seconds += time.perf_counter() - tick
    with torch.no_grad():
        device = policy.device
        frame = frames_to_tensors(live.observation, keys)
        next_value = policy.get_value(
            {k: v.to(device) for k, v in frame.items()},
            live.prev_action.to(device),
            live.start.to(device),
            live.state,
        ).cpu()
    rollout = Rollout(
        frames=frames,
        prev_actions=columns["prev"],
        starts=columns["start"],
        actions=columns["action"],
        logprobs=columns["logprob"],
        values=columns["value"],
        rewards=columns["reward"],
        dones=columns["done"],
        initial_state=initial_state,
        expert_actions=columns["label"],
    )
    return rollout, next_value, timing


def _act(
    policy: RecurrentPolicy,
    live: Live,
    frames: dict[str, Tensor],
    columns: dict[str, Tensor],
    t: int,
    rows: slice,
    keys: tuple[str, ...],
) -> Tensor:
    """Sample the actions of environments ``rows`` at step ``t`` and record what they saw."""
    device = policy.device
    observed = frames_to_tensors({k: live.observation[k][rows] for k in keys}, keys)
    frame = policy.cache_images({k: v.to(device) for k, v in observed.items()})
    store_frame(frames, t, rows, {**frame, **observed})  # observations from the host copy
    with torch.no_grad():
        action, logprob, value, state = policy.get_action_and_value(
            frame,
            live.prev_action[rows].to(device),
            live.start[rows].to(device),
            {k: v[rows] for k, v in live.state.items()},
        )
    for k, v in state.items():
        live.state[k][rows] = v
    action = action.cpu()
    columns["label"][t, rows] = torch.as_tensor(live.labels[rows])  # the frame acted on
    columns["prev"][t, rows] = live.prev_action[rows]
    columns["start"][t, rows] = live.start[rows]
    columns["action"][t, rows] = action
    columns["logprob"][t, rows] = logprob.cpu()
    columns["value"][t, rows] = value.cpu()
    live.prev_action[rows] = action
    return action


def store_frame(frames: dict[str, Tensor], t: int, rows: slice, frame: dict[str, Tensor]) -> None:
    """Keep ``frame`` (rows, ...) at step ``t`` of the (T, E, ...) ``frames``; a key the
    buffer lacks (a frozen encoder's outputs, :meth:`RecurrentPolicy.cache_images`) gets
    a buffer shaped as the others."""
    steps, count = next(iter(frames.values())).shape[:2]
    for k, v in frame.items():
        if k not in frames:
            frames[k] = torch.empty(steps, count, *v.shape[1:], dtype=v.dtype)
        frames[k][t, rows] = v.cpu()


def _record_step(
    live: Live,
    columns: dict[str, Tensor],
    t: int,
    rows: slice,
    result: StepResult,
    finished: deque[dict[str, float]],
) -> None:
    """Take in a group's step ``t``: rewards, dones, finished episodes, next observations."""
    observation, reward, terminated, truncated, infos = result
    done = np.logical_or(terminated, truncated)
    for k in live.observation:
        live.observation[k][rows] = observation[k]
    returns = live.returns[rows]
    returns += reward
    for index, metrics in finished_episodes(infos):
        finished.append({**metrics, "return": float(returns[index])})
        returns[index] = 0.0
    columns["reward"][t, rows] = torch.as_tensor(reward, dtype=torch.float32)
    columns["done"][t, rows] = torch.as_tensor(done, dtype=torch.float32)
    live.start[rows] = torch.as_tensor(done, dtype=torch.float32)
    live.labels[rows] = expert_labels(infos, rows.stop - rows.start)


def _dtype(array: np.ndarray) -> torch.dtype:
    return torch.from_numpy(np.asarray(array)[:0]).dtype


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
