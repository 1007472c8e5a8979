"""The periodic val evaluation of a training run (``--eval-every``, ``--eval-episodes``).

It plays episodes through the evaluator (:mod:`multion_agents.evaluate`), which loads learned
agents, so it sits above both: ``multion train`` builds it and passes it to the run
(:class:`multion_agents.learned.training_run.TrainingRun`), and the training code never
imports the evaluator.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from multion.config.codec import env_config_to_dict
from multion.config.task import EnvConfig, TaskConfig
from multion_agents.evaluate import (
    EvalSettings,
    episode_seed,
    local_env_factory,
    run_episode,
    select_episodes,
)
from multion_agents.learned.agent import agent_class_for_policy
from multion_agents.learned.policy import RecurrentPolicy
from multion_agents.learned.rollout_envs import SUMMARY_METRICS

_DEFAULTS = EnvConfig()


@dataclass(frozen=True)
class ValEvaluation:
    """Mean val metrics of the current policy over ``episodes`` evenly spaced packaged val
    episodes of an ``num_goals``-ON task, played in this process with the task's own step limit
    (a training ``--max-steps`` does not apply)."""

    episodes: int
    seed: int
    num_goals: int

    def __call__(self, policy: RecurrentPolicy, env_config: EnvConfig) -> dict[str, float]:
        config = replace(
            env_config,
            split="val",
            task=replace(env_config.task, max_steps=TaskConfig().max_steps),
            sensors=tuple(dict.fromkeys([*policy.sensors, "gps"])),
            episodes_per_scene=_DEFAULTS.episodes_per_scene,
        )
        chosen = select_episodes(
            EvalSettings(agent="", num_goals=self.num_goals, split="val", episodes=self.episodes)
        )
        agent = agent_class_for_policy(policy, {})(seed=self.seed)
        env = local_env_factory()(env_config_to_dict(config))
        try:
            records = []
            for index, episode in enumerate(chosen):
                agent.seed(episode_seed(self.seed, index))
                records.append(run_episode(env, agent, episode, index).metrics)
        finally:
            env.close()
            policy.train()
        return {k: float(np.mean([r[k] for r in records])) for k in SUMMARY_METRICS}
