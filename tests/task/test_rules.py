"""Task rules with numbers worked out by hand in the empty room ``room-6x4``.

The room's free interior is x∈[0, 6], y∈[0, 4]; the agent (radius 0.1) may stand on
x∈[0.1, 5.9], y∈[0.1, 3.9]. A goal at (4.5, 2.0) has a 0.05 m footprint; on the 0.05 m grid its
nearest navigable footprint cell towards the start is x = 4.45, so from (1.0, 2.0) the geodesic
distance is 3.45 m, and every forward step along +x brings the agent 0.25 m closer.
"""

import math

import numpy as np
import pytest

from multion.config.episode import Episode, Goal
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import EpisodeOverError, MultiONEnv
from multion_client.constants import Action

F, FWD, LEFT, RIGHT = Action.FOUND, Action.MOVE_FORWARD, Action.TURN_LEFT, Action.TURN_RIGHT
RED, GREEN = 0, 1


def make_env(goals, start=(1.0, 2.0), yaw=0.0, **task):
    task.setdefault("num_goals", len(goals))
    episode = Episode(
        "hand", "room-6x4", (*start, 0.0), yaw, tuple(Goal(c, (x, y, 0.0)) for c, (x, y) in goals)
    )
    config = EnvConfig(task=TaskConfig(**task), sensors=("goal", "gps", "compass"))
    return MultiONEnv(config, episodes=[episode])


def run(env, actions):
    total, result = 0.0, None
    for action in actions:
        result = env.step(action)
        total += result[1]
    return total, result


def test_straight_line_success_and_spl():
    env = make_env([(RED, (4.5, 2.0))])
    obs, info = env.reset(seed=0)
    assert info["metrics"]["distance_to_goal"] == pytest.approx(3.45, abs=0.01)
    total, (obs, reward, terminated, truncated, info) = run(env, [FWD] * 8 + [F])
    m = info["metrics"]
    assert terminated and not truncated
    assert m["success"] == 1.0 and m["progress"] == 1.0 and m["end_reason"] == "success"
    assert m["steps"] == 9 and m["path_length"] == pytest.approx(2.0)
    # d = 3.45 > p = 2.0, so SPL = 1 (stopping 1.45 m short is allowed)
    assert m["spl"] == pytest.approx(1.0) and m["ppl"] == pytest.approx(1.0)
    assert reward == pytest.approx(3.0 - 0.01)
    # rewards: 9 × slack, 2.0 m closer, +3 for the FOUND
    assert total == pytest.approx(-0.09 + 2.0 + 3.0, abs=0.01)
    assert obs["gps"] == pytest.approx([2.0, 0.0], abs=1e-6)


def test_overshoot_lowers_spl():
    env = make_env([(RED, (4.5, 2.0))])
    env.reset(seed=0)
    # 18 steps: x = 5.5, 0.95 m past the footprint edge at 4.55 (still within 1.5 m)
    _, (_, _, terminated, _, info) = run(env, [FWD] * 18 + [F])
    m = info["metrics"]
    assert terminated and m["success"] == 1.0
    assert m["path_length"] == pytest.approx(4.5)
    assert m["spl"] == pytest.approx(3.45 / 4.5, abs=0.005)


def test_wrong_found_ends_episode():
    env = make_env([(RED, (4.5, 2.0))])
    env.reset(seed=0)
    _, _, terminated, truncated, info = env.step(F)
    m = info["metrics"]
    assert terminated and not truncated
    assert m["end_reason"] == "wrong_found" and m["success"] == 0.0 and m["spl"] == 0.0
    with pytest.raises(EpisodeOverError):
        env.step(FWD)


def test_found_budget_allows_wrong_founds():
    env = make_env([(RED, (4.5, 2.0))], found_budget=2)
    env.reset(seed=0)
    for _ in range(2):
        _, reward, terminated, _, info = env.step(F)
        assert not terminated and reward == pytest.approx(-0.01)
    _, _, terminated, _, info = env.step(F)
    assert terminated and info["metrics"]["wrong_founds"] == 3
    assert info["metrics"]["end_reason"] == "wrong_found"


def test_found_budget_then_success():
    env = make_env([(RED, (4.5, 2.0))], found_budget=1)
    env.reset(seed=0)
    _, (_, _, terminated, _, info) = run(env, [F] + [FWD] * 8 + [F])
    assert terminated and info["metrics"]["success"] == 1.0 and info["metrics"]["wrong_founds"] == 1


def test_step_limit_truncates():
    env = make_env([(RED, (4.5, 2.0))], max_steps=5)
    env.reset(seed=0)
    for step in range(1, 6):
        _, _, terminated, truncated, info = env.step(LEFT)
        assert terminated is False
        assert truncated is (step == 5)
    assert info["metrics"]["end_reason"] == "max_steps" and info["metrics"]["steps"] == 5


def test_two_goals_progress_and_ppl():
    # g1 red at (4.5, 2), g2 green back at (1.0, 2): d(g1 → g2) = 4.5 - 1.05 = 3.45
    env = make_env([(RED, (4.5, 2.0)), (GREEN, (1.0, 2.0))])
    obs, _ = env.reset(seed=0)
    assert obs["goal"] == RED
    _, (obs, reward, terminated, _, info) = run(env, [FWD] * 12 + [F])  # x = 4.0, found g1
    assert not terminated and reward == pytest.approx(2.99)
    assert obs["goal"] == GREEN
    assert info["metrics"]["distance_to_goal"] == pytest.approx(2.95, abs=0.01)
    # turn around (6 × 30°), walk 0.5 m back to x = 3.5 (2.45 m from g2), call FOUND: wrong
    _, (obs, _, terminated, _, info) = run(env, [LEFT] * 6 + [FWD] * 2 + [F])
    m = info["metrics"]
    assert terminated and m["end_reason"] == "wrong_found"
    assert m["progress"] == 0.5 and m["success"] == 0.0 and m["spl"] == 0.0
    assert m["path_length"] == pytest.approx(3.5)
    assert m["ppl"] == pytest.approx(0.5 * 3.45 / 3.5, abs=0.003)
    # the reference code's variant uses the path length at the last correct FOUND (3.0 m)
    assert m["path_length_at_found"] == pytest.approx([3.0])
    assert m["ppl_reference"] == pytest.approx(0.5 * 3.45 / 3.45, abs=0.003)
    assert obs["compass"][0] == pytest.approx(math.pi, abs=1e-5) or obs["compass"][
        0
    ] == pytest.approx(-math.pi, abs=1e-5)


def test_two_goals_success_spl():
    env = make_env([(RED, (4.5, 2.0)), (GREEN, (1.0, 2.0))])
    env.reset(seed=0)
    _, (_, _, terminated, _, info) = run(env, [FWD] * 12 + [F] + [LEFT] * 6 + [FWD] * 6 + [F])
    m = info["metrics"]
    assert terminated and m["success"] == 1.0 and m["goals_found"] == 2
    # x = 2.5 is 1.45 m from g2's footprint; p = 4.5 < d = 6.9
    assert m["path_length"] == pytest.approx(4.5)
    assert m["spl"] == pytest.approx(1.0)


def test_collision_leaves_agent_in_place():
    env = make_env([(RED, (4.5, 2.0))], start=(0.5, 2.0), yaw=math.pi)  # facing the x = 0 wall
    env.reset(seed=0)
    obs, _, _, _, info = env.step(FWD)  # to x = 0.25: fine
    assert info["metrics"]["collisions"] == 0
    obs, reward, _, _, info = env.step(FWD)  # to x = 0.0: the body would be in the wall
    assert info["metrics"]["collisions"] == 1
    assert info["metrics"]["path_length"] == pytest.approx(0.25)
    assert obs["gps"] == pytest.approx(
        [0.25, 0.0], abs=1e-6
    )  # 0.25 m ahead of the start, no sliding
    assert reward == pytest.approx(-0.01)


def test_illegal_action_is_refused():
    env = make_env([(RED, (4.5, 2.0))])
    env.reset(seed=0)
    for bad in (4, -1, "left", 1.5, 1.0, True, np.float64(1.0), np.array([1])):
        with pytest.raises(ValueError, match="illegal action .*; actions are integers: 0 FOUND"):
            env.step(bad)
    # a refused action does not count as a step; numpy integers are actions
    _, _, _, _, info = env.step(FWD)
    for good in (np.int64(2), np.uint8(3), np.array(1)):
        _, _, _, _, info = env.step(good)
    assert info["metrics"]["steps"] == 4


def test_bad_seeds_and_reset_options_are_refused():
    env = make_env([(RED, (4.5, 2.0))])
    for seed in (-1, 2**63, 1.0, "0", True):
        with pytest.raises(ValueError, match=r"seed must be an int in \[0, 9223372036854775807\]"):
            env.reset(seed=seed)
    for options, match in (
        ({"episode_idx": 0}, r"unknown reset option\(s\) \['episode_idx'\]"),
        ({"episode_index": 0.0}, "'episode_index' must be an int"),
        ({"episode_index": 0, "episode_id": "hand"}, "at most one"),
    ):
        with pytest.raises(ValueError, match=match):
            env.reset(options=options)
    env.reset(seed=2**63 - 1, options={"episode_id": "hand"})


def test_wrong_found_penalty_is_subtracted_only_from_wrong_founds():
    env = make_env([(RED, (4.5, 2.0))], wrong_found_penalty=2.5, found_budget=1)
    env.reset(seed=0)
    assert env.step(F)[1] == pytest.approx(-0.01 - 2.5)
    total, (_, reward, terminated, _, _) = run(env, [FWD] * 8 + [F])
    assert terminated and reward == pytest.approx(3.0 - 0.01)  # a correct FOUND is not penalised
