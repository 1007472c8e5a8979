"""Expert labels for imitation: an expert's action at every state a learner visits.

``multion train --imitation-coef C`` adds ``C`` × the cross-entropy between the policy and
these labels to PPO's loss. The learner stays in control: the labels are the expert's actions
on the learner's own states, as in DAgger (Ross et al., 2011) with β = 0, so the learner is
also taught how to recover from its own mistakes. The expert (``--expert``) runs beside each
simulator, in the training worker processes, and only during training:

* ``oracle-planner`` (:mod:`multion_agents.baselines.oracle_planner`, the default) plans on a
  0.1 m oracle map of the whole house: it walks to a goal the learner has not seen, which a
  learner without that map cannot imitate;
* ``explorer`` (:mod:`multion_agents.baselines.explorer`) reads what the learner reads (RGB-D at
  the learner's image size, the goal, GPS and compass): it searches the frontier of the ground
  it has seen until the goal shows, then walks there and calls FOUND, all of which the learner
  can learn from its own observations.
"""

from __future__ import annotations

import sys
from abc import ABC, abstractmethod
from dataclasses import asdict
from typing import Any, ClassVar, SupportsFloat

import gymnasium as gym
import numpy as np

from multion.config.codec import env_config_to_dict
from multion.config.task import MapConfig
from multion.task.env import MultiONEnv
from multion.task.maps import OracleMap
from multion_agents.baselines.explorer import ExplorerAgent
from multion_agents.baselines.oracle_planner import OraclePlannerAgent, OraclePlannerSettings

EXPERT_ACTION = "expert_action"
"""The info key of an imitation label: the expert's action for the observation returned with it
(:class:`ExpertLabels`)."""
EXPERT_SENSORS = ("goal", "gps", "compass")
"""Sensors the oracle planner reads each step."""
EXPERT_SETTINGS = OraclePlannerSettings(stuck_visits=sys.maxsize)
"""The planner as the expert: without lattice searches (see ``OraclePlannerLabels``)."""


class ExpertLabels(gym.Wrapper[dict[str, np.ndarray], int, dict[str, np.ndarray], int], ABC):
    """Adds ``info["expert_action"]`` to every reset and to every step that does not end the
    episode: what the expert would do next, told before each step what the learner did."""

    sensors: ClassVar[tuple[str, ...]]
    """What the expert reads each step (the training env adds them; the policy ignores them)."""
    called: ClassVar[str]
    """How messages name the expert."""

    def __init__(self, env: MultiONEnv) -> None:
        missing = [s for s in self.sensors if s not in env.config.sensors]
        if missing:
            raise ValueError(f"the {self.called} needs sensors {missing} in the env config")
        super().__init__(env)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        observation, info = self.env.reset(seed=seed, options=options)
        self._start()
        info[EXPERT_ACTION] = self._label(observation)
        return observation, info

    def step(
        self, action: int
    ) -> tuple[dict[str, np.ndarray], SupportsFloat, bool, bool, dict[str, Any]]:
        self._took(int(action))
        observation, reward, terminated, truncated, info = self.env.step(action)
        if not (terminated or truncated):
            info[EXPERT_ACTION] = self._label(observation)
        return observation, reward, terminated, truncated, info

    @abstractmethod
    def _start(self) -> None:
        """A new episode has begun (the env is reset)."""

    @abstractmethod
    def _took(self, action: int) -> None:
        """The learner takes ``action`` (whatever the last label said)."""

    @abstractmethod
    def _label(self, observation: dict[str, np.ndarray]) -> int:
        """The expert's action for ``observation``."""


class OraclePlannerLabels(ExpertLabels):
    """Labels from ``oracle-planner``."""

    sensors = EXPERT_SENSORS
    called = "expert"

    def __init__(self, env: MultiONEnv) -> None:
        super().__init__(env)
        self._multion = env
        # no lattice searches: they answer the planner's own loops, but a learner turning on the
        # spot comes back to a position every step, and labels would then be search moves most
        # of the time (87 % of a random learner's steps in val houses); labels stay a function
        # of the state and the map
        self.planner = OraclePlannerAgent(settings=EXPERT_SETTINGS)
        """The expert (``replans`` counts what it had to redo)."""
        maps = OraclePlannerAgent.config_overrides["maps"]
        self._map_config = MapConfig(**maps)
        # the planner acts in this env, with its own oracle map (the env's may be coarser)
        self.planner.configure({**env_config_to_dict(env.config), "maps": asdict(self._map_config)})
        self._oracle: OracleMap | None = None
        self._start_map = np.zeros((0, 0, 2), dtype=np.uint8)

    def _start(self) -> None:
        self.planner.reset()
        self._start_map = self._planner_map()

    def _took(self, action: int) -> None:
        self.planner.took(action)

    def _planner_map(self) -> np.ndarray:
        """The oracle map the planner reads at the start: its own cells, around the start."""
        env = self._multion
        grid, episode = env.sim.grid, env.episode
        assert grid is not None and episode is not None
        if self._oracle is None or self._oracle.grid is not grid:  # a new scene
            self._oracle = OracleMap(grid, self._map_config)
        self._oracle.set_goals((*episode.goals, *episode.distractors))
        return self._oracle.egocentric(self._oracle.layers, env.sim.position, env.sim.yaw)

    def _label(self, observation: dict[str, np.ndarray]) -> int:
        seen = {key: observation[key] for key in EXPERT_SENSORS}
        return int(self.planner.act({**seen, "oracle_map": self._start_map}))


class ExplorerLabels(ExpertLabels):
    """Labels from ``explorer``: its map is built from the observations of the learner's own
    path, and it is told each action the learner took (``ExplorerAgent.took``)."""

    sensors = ExplorerAgent.sensors
    called = "explorer"

    def __init__(self, env: MultiONEnv) -> None:
        super().__init__(env)
        self.explorer = ExplorerAgent()
        self.explorer.configure(env_config_to_dict(env.config))

    def _start(self) -> None:
        self.explorer.reset()

    def _took(self, action: int) -> None:
        self.explorer.took(action)

    def _label(self, observation: dict[str, np.ndarray]) -> int:
        return int(self.explorer.act({key: observation[key] for key in ExplorerAgent.sensors}))


EXPERT_LABELS: dict[str, type[ExpertLabels]] = {
    "oracle-planner": OraclePlannerLabels,
    "explorer": ExplorerLabels,
}
"""Each expert of ``train_options.EXPERTS`` (``--expert``) by name."""
