"""The rollout's environments in groups that take turns, so that acting overlaps simulation.

The policy acts for one group while the other group's simulator processes step: on a machine
whose cores the simulators share with the learner, acting otherwise leaves a core idle every
step. Local environments form two groups of worker processes (each process running one
environment or several, ``envs_per_process``); environments on MultiON servers
form one (their requests are already spread over servers).

The groups are seeded as one vector env of all the environments would be (environment ``i``
with ``seed + i``), and the policy samples each group's actions in turn, rows in order, as it
sampled all rows at once before: a rollout is the same with one group or two.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium.vector import AsyncVectorEnv, VectorEnv

from multion_agents.learned.env_workers import SharedProcessVectorEnv
from multion_agents.learned.rollout_envs import TrainingWrappers, make_vector_env

StepResult = tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]


@dataclass
class EnvGroups:
    """Vector envs over consecutive slices of the environments (``rows[g]`` is group g's)."""

    groups: list[VectorEnv]
    rows: list[slice] = field(init=False)
    _pending: dict[int, StepResult] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.rows, first = [], 0
        for group in self.groups:
            self.rows.append(slice(first, first + group.num_envs))
            first += group.num_envs

    @property
    def num_envs(self) -> int:
        return sum(g.num_envs for g in self.groups)

    def reset(self, seed: int) -> tuple[dict[str, np.ndarray], list[dict[str, Any]]]:
        """Reset every environment (``i`` seeded with ``seed + i``): the observations of all,
        and each group's infos."""
        observations, infos = [], []
        for group, rows in zip(self.groups, self.rows, strict=True):
            observation, info = group.reset(seed=seed + rows.start)
            observations.append(observation)
            infos.append(info)
        return {k: np.concatenate([o[k] for o in observations]) for k in observations[0]}, infos

    def start_step(self, index: int, actions: np.ndarray) -> None:
        """Send group ``index`` its actions (local workers start stepping at once)."""
        group = self.groups[index]
        if isinstance(group, AsyncVectorEnv | SharedProcessVectorEnv):
            group.step_async(actions)
        else:
            self._pending[index] = group.step(actions)

    def finish_step(self, index: int) -> StepResult:
        """Wait for group ``index``'s step: observations, rewards, terminated, truncated, infos."""
        group = self.groups[index]
        if isinstance(group, AsyncVectorEnv | SharedProcessVectorEnv):
            return group.step_wait()
        return self._pending.pop(index)

    def close(self, terminate: bool = False) -> None:
        for group in self.groups:
            group.close(terminate=terminate)


def make_env_groups(
    config: dict[str, Any],
    num_envs: int,
    servers: Sequence[str] = (),
    wrappers: TrainingWrappers = TrainingWrappers(),
    envs_per_process: int = 1,
) -> EnvGroups:
    """Two groups of local worker processes (one when there is a single environment), or one
    group on ``servers``; ``envs_per_process`` local environments share each process."""
    if servers or num_envs < 2:
        return EnvGroups([make_vector_env(config, num_envs, servers, wrappers, envs_per_process)])
    half = num_envs // 2
    return EnvGroups(
        [
            make_vector_env(config, n, (), wrappers, envs_per_process)
            for n in (half, num_envs - half)
        ]
    )
