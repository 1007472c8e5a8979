"""``closest_to_goal``: the shortest geodesic distance to the current goal since it became
current, worked out by hand in the empty room ``room-6x4`` (as in ``test_rules.py``: from
(1.0, 2.0) facing +x, a goal at (4.5, 2.0) is 3.45 m away and each forward step is 0.25 m)."""

from __future__ import annotations

import pytest
from test_rules import FWD, GREEN, LEFT, RED, F, make_env, run

from multion.config.task import TaskConfig
from multion.task.env import MultiONEnv
from multion_client.constants import Action

ABOUT_TURN = [LEFT] * 6  # 6 × 30°


def metrics_after(env: MultiONEnv, actions: list[Action]) -> dict:
    return run(env, actions)[1][4]["metrics"]


def test_it_keeps_the_closest_approach_when_the_agent_walks_away() -> None:
    env = make_env([(RED, (4.5, 2.0))])
    _, info = env.reset(seed=0)
    assert info["metrics"]["closest_to_goal"] == pytest.approx(3.45, abs=0.01)
    m = metrics_after(env, [FWD] * 4)
    assert m["closest_to_goal"] == pytest.approx(2.45, abs=0.01) == m["distance_to_goal"]
    m = metrics_after(env, [*ABOUT_TURN, FWD, FWD])
    assert m["distance_to_goal"] == pytest.approx(2.95, abs=0.01)
    assert m["closest_to_goal"] == pytest.approx(2.45, abs=0.01)


def test_a_step_limit_within_reach_reads_below_the_success_distance() -> None:
    env = make_env([(RED, (4.5, 2.0))])
    env.reset(seed=0)
    # 8 steps: 1.45 m from the goal, within reach (1.5 m); then away without calling FOUND
    m = metrics_after(env, [FWD] * 8 + ABOUT_TURN + [FWD] * 4)
    assert m["success"] == 0.0 and m["distance_to_goal"] == pytest.approx(2.45, abs=0.01)
    assert m["closest_to_goal"] == pytest.approx(1.45, abs=0.01)
    assert m["closest_to_goal"] <= TaskConfig().success_distance < m["distance_to_goal"]


def test_a_found_goal_starts_it_again_from_the_next_goal() -> None:
    env = make_env([(RED, (4.5, 2.0)), (GREEN, (1.0, 2.0))])
    env.reset(seed=0)
    m = metrics_after(env, [FWD] * 8 + [F])
    assert m["goals_found"] == 1
    # the next goal's distance, not the 1.45 m of the goal just found
    assert m["closest_to_goal"] == m["distance_to_goal"] > 1.5
    before = m["distance_to_goal"]
    m = metrics_after(env, [*ABOUT_TURN, FWD, FWD])
    assert m["closest_to_goal"] == pytest.approx(before - 0.5, abs=0.01)
