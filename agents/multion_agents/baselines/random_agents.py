"""The paper's random baselines (Table 3): ``Rand`` and ``Rand+OracleFound``."""

from __future__ import annotations

from typing import ClassVar

from multion_agents.agent import Agent, Observation
from multion_client.constants import NUM_ACTIONS, Action

MOTIONS = (Action.MOVE_FORWARD, Action.TURN_LEFT, Action.TURN_RIGHT)


class RandomAgent(Agent):
    """``Rand``: every step an action drawn uniformly from all four, FOUND included.

    A random FOUND ends the episode (wrong FOUND), so this agent almost never finds anything.
    """

    sensors: ClassVar[tuple[str, ...]] = ("goal",)

    def reset(self) -> None:
        pass

    def act(self, observation: Observation) -> int:
        return int(self.rng.integers(NUM_ACTIONS))


class RandomOracleFoundAgent(Agent):
    """``Rand+OracleFound``: random motion, and FOUND exactly when an oracle says the current goal
    is within the success distance (the ``goal_distance`` sensor)."""

    sensors: ClassVar[tuple[str, ...]] = ("goal", "goal_distance")
    success_distance: float = 1.5

    def reset(self) -> None:
        pass

    def act(self, observation: Observation) -> int:
        if float(observation["goal_distance"][0]) <= self.success_distance:
            return int(Action.FOUND)
        return int(MOTIONS[int(self.rng.integers(len(MOTIONS)))])
