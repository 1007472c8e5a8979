"""Vector environments for training: in-process simulator workers, or MultiON servers.

Both kinds auto-reset with Gymnasium's ``SAME_STEP`` mode: the step that ends an episode
returns its reward and done flags, the next episode's first observation, and the finished
episode's metrics in ``infos["final_info"]``. The trainer never sees a step whose action is
ignored, and the rollout code is the same for local and remote environments.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AsyncVectorEnv, AutoresetMode, VectorEnv

from multion.config.codec import env_config_from_dict
from multion.config.ranges import ConfigError
from multion.config.task import EnvConfig
from multion.task.env import MultiONEnv
from multion_agents.agent import merge_overrides
from multion_agents.learned.env_workers import SharedProcessVectorEnv
from multion_agents.learned.expert import EXPERT_ACTION, EXPERT_SENSORS, OraclePlannerLabels
from multion_agents.learned.train_options import (
    FOUND_BUDGET_UNLIMITED,
    Curriculum,
    FoundCurriculum,
)
from multion_client.vector import RemoteVectorEnv

SUMMARY_METRICS = ("success", "progress", "spl", "ppl", "steps")
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


def _make_local_env(config: dict[str, Any], expert: bool = False) -> gym.Env:
    # module-level so that spawn-started workers can unpickle it

    if not expert:
        return MultiONEnv(env_config_from_dict(config))

    sensors = list(dict.fromkeys([*config["sensors"], *EXPERT_SENSORS]))
    return OraclePlannerLabels(MultiONEnv(env_config_from_dict({**config, "sensors": sensors})))


def make_vector_env(
    config: dict[str, Any],
    num_envs: int,
    servers: Sequence[str] = (),
    expert: bool = False,
    envs_per_process: int = 1,
) -> VectorEnv:
    """``num_envs`` environments: on ``servers`` (spread evenly) or in local worker processes,
    ``envs_per_process`` in each (1: gymnasium's ``AsyncVectorEnv``, one process each; more:
    :class:`.env_workers.SharedProcessVectorEnv`, whose envs share a process's goal-site cache).
    ``expert``: local environments whose infos carry the oracle planner's action
    (:mod:`.expert`)."""
    if envs_per_process < 1:
        raise ConfigError(f"--envs-per-process {envs_per_process}: at least 1")
    if servers:
        if expert:
            raise ConfigError(
                "--imitation-coef labels steps with a planner beside the simulator: it needs "
                "local environments, not --server"
            )

        counts = [
            num_envs // len(servers) + (i < num_envs % len(servers)) for i in range(len(servers))
        ]
        if min(counts) < 1:
            raise ConfigError(f"{num_envs} envs cannot be spread over {len(servers)} servers")
        return RemoteVectorEnv(list(servers), counts, config)
    factories = [functools.partial(_make_local_env, config, expert) for _ in range(num_envs)]
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
            (int(index), {k: float(metrics[k][index]) for k in SUMMARY_METRICS if k in metrics})
        )
    return out
