"""The periodic val evaluation of a training run (``--eval-every``, ``--eval-episodes``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from multion_agents.learned.policy import RecurrentPolicy
from multion_agents.learned.rollout_envs import SUMMARY_METRICS


def evaluate_policy(
    policy: RecurrentPolicy,
    episodes: int,
    seed: int,
    env_config: dict[str, Any],
    num_goals: int,
) -> dict[str, float]:
    """Mean val metrics of the current policy over ``episodes`` evenly spaced packaged
    val episodes, played in this process with the task's own step limit."""
    from multion_agents.evaluate import (
        EvalSettings,
        episode_seed,
        local_env_factory,
        run_episode,
        select_episodes,
    )
    from multion_agents.learned.agent import agent_class_for_policy

    config = {
        **env_config,
        "split": "val",
        "task": {k: v for k, v in env_config["task"].items() if k != "max_steps"},
    }
    config["sensors"] = list(dict.fromkeys([*policy.sensors, "gps"]))
    config.pop("episodes_per_scene", None)
    chosen = select_episodes(
        EvalSettings(agent="", num_goals=num_goals, split="val", episodes=episodes)
    )
    agent = agent_class_for_policy(policy, {})(seed=seed)
    env = local_env_factory()(config)
    try:
        records = []
        for index, episode in enumerate(chosen):
            agent.seed(episode_seed(seed, index))
            records.append(run_episode(env, agent, episode, index).metrics)
    finally:
        env.close()
        policy.train()
    return {k: float(np.mean([r[k] for r in records])) for k in SUMMARY_METRICS}
