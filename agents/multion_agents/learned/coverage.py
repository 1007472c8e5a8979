"""``--coverage-reward R``: an exploration bonus for visiting new ground (training only).

Ye et al., "Auxiliary Tasks and Exploration Enable ObjectGoal Navigation" (ICCV 2021), add to
the task's reward, at every step ``t`` of an episode, ``R · 0.995^t / n`` where ``n`` counts the
steps the agent has spent in its current cell of a 2.5 m grid in the episode's start frame
(joel99/objectnav ``habitat/tasks/coverage/coverage.py`` l. 55-170, ``CoverageExplorationReward``;
``habitat/config/default.py`` l. 184-188: ``REWARD`` 0.25, ``ATTENUATION`` 0.995, ``VISIT_EXP`` 1;
``configs/tasks/objectnav_mp3d_full.yaml`` l. 52-58: ``GRID_DELTA`` 2.5, egocentric). Their agent
moves like MultiON's (0.25 m steps, 30° turns).

Why here (issue 51): the learn-to-see ``no-map`` agent never comes within 1.5 m of the goal in
60 of 100 val episodes, though it walks for 2500 steps (``multion diagnose``); an agent without
a map can only learn to search from the task's reward, whose geodesic shaping says nothing it
can see until the goal is in view. The bonus pays for new ground, decaying over the episode so
that late in an episode the task's reward dominates.

:class:`CoverageBonus` wraps a local training environment (in its worker process) and reads the
``gps`` sensor, which the training env adds (the policy does not read it). Evaluation never has
the bonus; the task's metrics are unchanged, only the reward PPO learns from.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from multion.task import measures

COVERAGE_SENSORS = ("gps",)
"""What the bonus reads each step (the training env adds it; the policy ignores it)."""
ATTENUATION = 0.995
"""The bonus's decay per step of the episode (Ye et al.'s ``ATTENUATION``)."""


def coverage_bonus(reward: float, step: int, visits: int) -> float:
    """The bonus at ``step`` (1 for the first step after reset) for a cell entered ``visits``
    times so far, this step included: ``reward · ATTENUATION^step / visits``."""
    return reward * ATTENUATION**step / visits


def visit_cell(gps: np.ndarray) -> tuple[int, int]:
    """The cell of the task's ``cells_visited`` grid (2.5 m, Ye et al.'s ``GRID_DELTA``) holding
    ``gps`` (ahead, left metres in the start frame)."""
    return measures.visit_cell(float(gps[0]), float(gps[1]))


class CoverageBonus(gym.Wrapper[dict[str, np.ndarray], int, dict[str, np.ndarray], int]):
    """Adds :func:`coverage_bonus` to every step's reward, from the ``gps`` sensor; the cell
    counts start afresh (the start cell visited once) at every reset."""

    def __init__(self, env: gym.Env[dict[str, np.ndarray], int], reward: float) -> None:
        space = env.observation_space
        sensors: set[str] = set(space.spaces) if isinstance(space, gym.spaces.Dict) else set()
        missing = [s for s in COVERAGE_SENSORS if s not in sensors]
        if missing:
            raise ValueError(f"the coverage bonus needs sensors {missing} in the env config")
        if not reward > 0:
            raise ValueError(f"coverage reward {reward}: above 0 (0 is no wrapper)")
        super().__init__(env)
        self.reward = reward
        self._visits: dict[tuple[int, int], int] = {}
        self._step = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        observation, info = self.env.reset(seed=seed, options=options)
        self._visits = {visit_cell(observation["gps"]): 1}
        self._step = 0
        return observation, info

    def step(
        self, action: int
    ) -> tuple[dict[str, np.ndarray], SupportsFloat, bool, bool, dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        self._step += 1
        cell = visit_cell(observation["gps"])
        self._visits[cell] = self._visits.get(cell, 0) + 1
        bonus = coverage_bonus(self.reward, self._step, self._visits[cell])
        return observation, float(reward) + bonus, terminated, truncated, info
