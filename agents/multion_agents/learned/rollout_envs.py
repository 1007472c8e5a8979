"""Vector environments for training: in-process simulator workers, or MultiON servers.

Both kinds auto-reset with Gymnasium's ``SAME_STEP`` mode: the step that ends an episode
returns its reward and done flags, the next episode's first observation, and the finished
episode's metrics in ``infos["final_info"]``. The trainer never sees a step whose action is
ignored, and the rollout code is the same for local and remote environments.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AsyncVectorEnv, AutoresetMode, VectorEnv

from multion.config.codec import env_config_from_dict
from multion.config.ranges import ConfigError
from multion.config.task import EnvConfig
from multion.task.env import MultiONEnv
from multion_agents.agent import merge_overrides
from multion_agents.learned.coverage import COVERAGE_SENSORS, CoverageBonus
from multion_agents.learned.env_workers import SharedProcessVectorEnv
from multion_agents.learned.expert import EXPERT_ACTION, EXPERT_LABELS
from multion_agents.learned.train_options import (
    FOUND_BUDGET_UNLIMITED,
    Curriculum,
    FoundCurriculum,
)
from multion_client.vector import RemoteVectorEnv

SUMMARY_METRICS = ("success", "progress", "spl", "ppl", "steps")
ENDING_METRICS = ("closest_to_goal", "wrong_founds")
"""Also kept of each finished training episode: how it got on with the goal it did not find
(``training_run``: the share that came within reach, the share with a wrong FOUND)."""
NO_LABEL = -1
"""The label of a step without one (the last step of an episode), left out of the loss."""


def training_env_config(
    num_goals: int,
    sensors: Sequence[str],
    image_size: int,
    split: str = "train",
    overrides: dict[str, dict[str, Any]] | None = None,
    max_steps: int | None = None,
    dataset: str | None = None,
) -> dict[str, Any]:
    """The env config (nested dicts, the server's wire form) a learned agent trains with."""
    config: dict[str, Any] = {
        "task": {"num_goals": num_goals},
        "camera": {"width": image_size, "height": image_size},
        "sensors": list(sensors),
        "split": split,
    }
    if max_steps is not None:
        config["task"]["max_steps"] = max_steps
    if dataset is not None:
        config["dataset"] = str(dataset)
    return merge_overrides(config, overrides or {})


def check_curriculum(curriculum: Curriculum, env_config: EnvConfig) -> None:
    """A ``ConfigError`` before any environment starts, rather than at a stage switch (a
    stage's distance out of range: the config's own, naming ``online_max_geodesic``)."""
    if not curriculum:
        return
    if env_config.dataset is not None:
        raise ConfigError("--curriculum samples episodes online; it cannot be used with --dataset")
    ends = [until for until, _ in curriculum]
    if ends[0] <= 0 or any(b <= a for a, b in zip(ends, ends[1:], strict=False)):
        raise ConfigError(
            f"--curriculum stages must end at increasing frame counts > 0, got {ends}"
        )
    for until, _ in curriculum:
        stage_config(env_config, curriculum, until - 1)  # each stage's range checked


def stage_config(
    env_config: EnvConfig,
    curriculum: Curriculum,
    frames: int,
    found: FoundCurriculum | None = None,
) -> EnvConfig:
    """The env config to train with once ``frames`` frames are done: the distance curriculum's
    stage, and during the FOUND curriculum (``found``) wrong FOUNDs that cost its penalty and
    end no episode."""
    if found is not None and frames < found.frames:
        task = replace(
            env_config.task,
            found_budget=FOUND_BUDGET_UNLIMITED,
            wrong_found_penalty=found.penalty,
        )
        env_config = replace(env_config, task=task)
    for until, metres in curriculum:
        if frames < until:
            return replace(env_config, online_max_geodesic=metres)
    return env_config


@dataclass(frozen=True)
class TrainingWrappers:
    """What local training environments add to the task, for training only."""

    expert: str = ""
    """Infos carry this expert's action (:mod:`.expert`, ``--imitation-coef``, ``--expert``;
    empty: none)."""
    coverage_reward: float = 0.0
    """Rewards carry an exploration bonus (:mod:`.coverage`, ``--coverage-reward``; 0: none)."""

    def options(self) -> tuple[tuple[str, bool], ...]:
        """Each wrapper's training option and whether it is on."""
        return (
            ("--imitation-coef", bool(self.expert)),
            ("--coverage-reward", self.coverage_reward > 0),
        )


def _make_local_env(config: dict[str, Any], wrappers: TrainingWrappers) -> gym.Env:
    # module-level so that spawn-started workers can unpickle it
    sensors = list(config["sensors"])
    labels = EXPERT_LABELS[wrappers.expert] if wrappers.expert else None
    if labels is not None:
        sensors += labels.sensors
    if wrappers.coverage_reward > 0:
        sensors += COVERAGE_SENSORS
    simulator = MultiONEnv(
        env_config_from_dict({**config, "sensors": list(dict.fromkeys(sensors))})
    )
    env: gym.Env[dict[str, np.ndarray], int] = (
        labels(simulator) if labels is not None else simulator
    )
    if wrappers.coverage_reward > 0:
        env = CoverageBonus(env, wrappers.coverage_reward)
    return env


def make_vector_env(
    config: dict[str, Any],
    num_envs: int,
    servers: Sequence[str] = (),
    wrappers: TrainingWrappers = TrainingWrappers(),
    envs_per_process: int = 1,
) -> VectorEnv:
    """``num_envs`` environments: on ``servers`` (spread evenly) or in local worker processes,
    ``envs_per_process`` in each (1: gymnasium's ``AsyncVectorEnv``, one process each; more:
    :class:`.env_workers.SharedProcessVectorEnv`, whose envs share a process's goal-site cache).
    ``wrappers``: what local environments add for training (the oracle planner's action in
    their infos, an exploration bonus in their rewards)."""
    if envs_per_process < 1:
        raise ConfigError(f"--envs-per-process {envs_per_process}: at least 1")
    if servers:
        local_only = [option for option, on in wrappers.options() if on]
        if local_only:
            raise ConfigError(
                f"{' and '.join(local_only)} work beside the simulator: each needs local "
                "environments, not --server"
            )

        counts = [
            num_envs // len(servers) + (i < num_envs % len(servers)) for i in range(len(servers))
        ]
        if min(counts) < 1:
            raise ConfigError(f"{num_envs} envs cannot be spread over {len(servers)} servers")
        return RemoteVectorEnv(list(servers), counts, config)
    factories = [functools.partial(_make_local_env, config, wrappers) for _ in range(num_envs)]
    if envs_per_process > 1:
        return SharedProcessVectorEnv(factories, envs_per_process)
    return AsyncVectorEnv(
        factories,
        context="spawn",
        autoreset_mode=AutoresetMode.SAME_STEP,
    )


def expert_labels(infos: dict[str, Any], num_envs: int) -> np.ndarray:
    """The expert's action for each environment's current observation (``NO_LABEL`` where
    there is none)."""
    labels = np.full(num_envs, NO_LABEL, dtype=np.int64)
    if EXPERT_ACTION in infos:
        mask = np.asarray(infos[f"_{EXPERT_ACTION}"], dtype=bool)
        labels[mask] = np.asarray(infos[EXPERT_ACTION])[mask]
    return labels


def finished_episodes(infos: dict[str, Any]) -> list[tuple[int, dict[str, float]]]:
    """(env index, summary metrics) of the episodes that ended at this step."""
    if "final_info" not in infos:
        return []
    final, mask = infos["final_info"], np.asarray(infos["_final_info"], dtype=bool)
    metrics = final.get("metrics", {})
    out = []
    for index in np.flatnonzero(mask):
        out.append(
            (
                int(index),
                {
                    k: float(metrics[k][index])
                    for k in (*SUMMARY_METRICS, *ENDING_METRICS)
                    if k in metrics
                },
            )
        )
    return out
