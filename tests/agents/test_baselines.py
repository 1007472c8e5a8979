"""The baselines do what they claim: planners solve episodes, random agents stay random."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multion.config.episode import Episode, Goal
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, MapConfig, TaskConfig
from multion.scenes.viz import gps_to_world
from multion.task.env import MultiONEnv
from multion_agents.agent import Agent, AgentError
from multion_agents.baselines.mapping import CameraModel, detect_goals, goal_shaped
from multion_agents.baselines.navigation import (
    StartFrameGrid,
    choose_action,
    distance_field,
    step_points,
    steps_ahead,
    two_step_action,
)
from multion_agents.evaluate import episode_seed, run_episode
from multion_agents.registry import make_agent
from multion_client.constants import GOAL_RGBA, Action
from v2_episodes import v2_episode


def _env(
    agent: Agent,
    num_goals: int,
    episodes: list[Episode],
    image: int = 64,
    max_steps: int = 2500,
) -> MultiONEnv:
    maps = MapConfig(**agent.config_overrides.get("maps", {}))
    config = EnvConfig(
        task=TaskConfig(num_goals=num_goals, max_steps=max_steps),
        maps=maps,
        camera=CameraConfig(width=image, height=image),
        sensors=tuple(dict.fromkeys([*agent.sensors, "gps"])),
    )
    return MultiONEnv(config, episodes=episodes)


def test_oracle_planner_solves_3on_episodes() -> None:
    # three episodes of one house (one grid build), among them a gap it once could not enter
    same_scene = [v2_episode(f"val-3-on-0000{k}") for k in range(3)]
    agent = make_agent("oracle-planner")
    env = _env(agent, 3, same_scene)
    records = [run_episode(env, agent, episode) for episode in same_scene]
    env.close()
    # val-3-on-00001 passes a gap one map cell wide at 45° between two pieces of furniture,
    # which it can enter only with two steps at different headings (it oscillated for 2,500
    # steps until it looked two steps ahead)
    assert "val-3-on-00001" in [r.episode_id for r in records]
    assert all(r.metrics["success"] == 1.0 for r in records), [r.metrics for r in records]
    assert all(r.metrics["spl"] > 0.7 for r in records)


def _play_planner(episode_id: str) -> tuple[dict[str, object], Agent]:
    """oracle-planner's metrics on one version 2 val episode, and the agent."""
    episode = v2_episode(episode_id)
    agent = make_agent("oracle-planner")
    env = _env(agent, episode.num_goals, [episode])
    record = run_episode(env, agent, episode)
    env.close()
    return record.metrics, agent


@pytest.mark.parametrize("episode_id", ["val-3-on-00960", "val-2-on-00910"])
def test_oracle_planner_gets_out_of_a_pocket_its_map_leads_it_into(episode_id: str) -> None:
    # the field led it into a pocket that steps leave only backwards, and back into it once
    # out: 2,500 steps, ~740 collisions, no goal. The way round needs steps away from the goal
    # to line up with a gap the 0.1 m map cannot resolve; a lattice search finds them
    metrics, agent = _play_planner(episode_id)
    assert metrics["success"] == 1.0, metrics
    assert metrics["steps"] < 400  # type: ignore[operator]
    assert agent.searches >= 1  # type: ignore[attr-defined]


def test_oracle_planner_finds_a_goal_its_map_cuts_off() -> None:
    # val-2-on-00650: on the 0.1 m map the second goal's cells are walled in, so the plan crawls
    # through occupied cells and its travel time never fell under the 1.0 m FOUND threshold,
    # while the agent stood 0.45 m (geodesic) from the goal: 2,500 steps, one goal
    metrics, _ = _play_planner("val-2-on-00650")
    assert metrics["success"] == 1.0, metrics
    assert metrics["steps"] < 400  # type: ignore[operator]


def test_explorer_finds_goals_in_a_room() -> None:
    goals = (Goal(0, (4.8, 3.2, 0.0)), Goal(7, (1.0, 0.8, 0.0)))
    episode = Episode("room-explore", "room-6x4", (1.0, 2.0, 0.0), math.pi, goals)
    agent = make_agent("explorer")
    env = _env(agent, 2, [episode], image=128)
    record = run_episode(env, agent, episode)
    assert record.metrics["success"] == 1.0, record.metrics
    # the map remembers both goal colours, placed within 20 cm
    known = agent.map.known_goals()  # type: ignore[attr-defined]
    assert set(known) == {0, 7}
    for goal in goals:
        world = gps_to_world(known[goal.category][None, :], episode)[0]
        assert np.hypot(*(world - goal.position[:2])) < 0.2
    env.close()


@pytest.mark.parametrize(
    ("episode_id", "image", "max_steps"),
    [
        # the goal colour seen during the first look around: a white plant pot, which colour
        # alone takes for the white goal; the agent used to press against it for 2,500 steps
        ("val-3-on-00250", 128, 700),
        # a cluttered corner where the margin kept round obstacles leaves the plan's only way
        # one cell wide: the agent used to turn on the spot for 2,400 steps
        ("val-1-on-00650", 256, 700),
        # the goal seen over a box 0.7 m away, 1.7 m round it: FOUND was called there
        ("val-1-on-00000", 256, 700),
        # a start where 8 of the 12 headings are refused: after two full turns without moving
        # the agent forgot the refused steps and retried them, and never moved in 700 steps
        ("val-2-on-00080", 128, 700),
        # a corridor whose lanes for the agent's centre are 0.05 m wide: no single step from
        # the mouth enters, only three (at 270°, 60°, 180°); the agent turned at the mouth
        # for the whole episode. It now succeeds after 665 steps (the rest is exploring)
        ("val-1-on-00460", 256, 800),
    ],
)
def test_explorer_gets_out_of_its_old_traps(episode_id: str, image: int, max_steps: int) -> None:
    episode = v2_episode(episode_id)
    num_goals = episode.num_goals
    agent = make_agent("explorer")
    env = _env(agent, num_goals, [episode], image=image, max_steps=max_steps)
    record = run_episode(env, agent, episode)
    env.close()
    assert record.metrics["success"] == 1.0, record.metrics


@pytest.mark.parametrize(
    "seed",
    # seeds 2 and 3, and the one `multion eval --seed 0` gave this episode before issue 53
    # seeded episodes by id (index 460 of the packaged 1-ON val dataset, which holds the same
    # episode under the same id)
    [2, 3, episode_seed(0, 460)],
)
def test_explorer_enters_the_corridor_of_val_1_on_00460_whatever_its_seed(seed: int) -> None:
    # at the corridor's mouth its random turns at a local minimum of the plan sent it into a
    # loop: a three-step route out and back that retried a refused step, 40 times, for 1,500
    # steps. Arriving at one position a third time it now searches the positions its steps
    # reach, trying no step twice (379 steps with seeds 2 and 3, 600 with the eval's seed)
    episode = v2_episode("val-1-on-00460")
    agent = make_agent("explorer")
    agent.seed(seed)
    env = _env(agent, 1, [episode], image=256, max_steps=800)
    record = run_episode(env, agent, episode)
    env.close()
    assert record.metrics["success"] == 1.0, record.metrics
    assert agent.searches >= 1  # type: ignore[attr-defined]


def test_random_oracle_found_calls_found_only_when_close() -> None:
    agent = make_agent("random-oracle-found", seed=0)
    agent.reset()
    far = {"goal": np.int64(0), "goal_distance": np.array([1.6], np.float32)}
    near = {"goal": np.int64(0), "goal_distance": np.array([1.5], np.float32)}
    assert all(agent.act(far) != Action.FOUND for _ in range(200))
    assert agent.act(near) == Action.FOUND


def test_random_uses_all_four_actions() -> None:
    agent = make_agent("random", seed=0)
    actions = {agent.act({"goal": np.int64(0)}) for _ in range(200)}
    assert actions == {0, 1, 2, 3}


def test_colour_detection_is_exact() -> None:
    image = np.full((20, 40, 3), (150, 140, 120), dtype=np.uint8)  # a muted wall
    image[5:15, 2:4] = np.array(GOAL_RGBA[4][:3]) * 200  # magenta, dimly lit
    image[5:15, 10:12] = 180  # white in shade
    image[5:15, 20:22] = 0  # black
    image[5:15, 30:32] = (199, 199, 190)  # a light scene grey: not white
    image[5:15, 34:36] = (115, 0, 0)  # red in a dark house (ambient 0.45)
    image[15:19, 2:4] = (200, 22, 18)  # a red sofa: goal-like, but its off channels are not 0
    image[15:19, 10:12] = (231, 231, 228)  # a white fridge: not exactly balanced
    image[15:19, 20:22] = (20, 20, 23)  # black paint: not 0
    found = detect_goals(image)
    assert sorted(found) == [0, 4, 6, 7]
    assert set(found[4][1].tolist()) == {2, 3}
    assert set(found[0][1].tolist()) == {34, 35} and set(found[7][0].tolist()) <= set(range(5, 15))


def test_goal_shape_tells_a_white_goal_from_white_paint() -> None:
    # under bright light white paint renders (255, 255, 255), exactly as a white goal does
    image = np.full((64, 64, 3), (150, 140, 120), dtype=np.uint8)
    image[20:50, 10:13] = 255  # a 0.1 m cylinder 1.4 m away: 3 pixels wide
    image[30:50, 30:50] = 255  # a plant pot at the same depth: 20 pixels, 0.7 m
    depth = np.full((64, 64, 1), (1.4 - 0.5) / 4.5, dtype=np.float32)
    found = detect_goals(image)
    assert set(found[7][1].tolist()) == set(range(10, 13)) | set(range(30, 50))
    shaped = goal_shaped(found, depth, CameraModel())
    assert set(shaped[7][1].tolist()) == {10, 11, 12}
    # the pot alone is no goal at all
    image[20:50, 10:13] = (150, 140, 120)
    assert goal_shaped(detect_goals(image), depth, CameraModel()) == {}


def test_start_frame_grid_round_trip() -> None:
    grid = StartFrameGrid(size=41, cell_size=0.1)
    rows, cols = grid.to_cell(np.array([[0.0, 0.0], [1.0, 0.5], [-0.3, -1.2]]))
    assert (rows[0], cols[0]) == (20, 20)  # the start is the centre cell
    assert (rows[1], cols[1]) == (10, 15)  # ahead is up, left is towards column 0
    back = grid.to_xy(rows, cols)
    assert back[2] == pytest.approx([-0.3, -1.2])


def test_oracle_planner_refuses_a_map_it_was_not_built_for() -> None:
    # a track's default oracle map (13 cells of 0.8 m) used to be read as 0.1 m cells until the
    # agent walked off it (IndexError); it now stops at once, saying which map it needs
    agent = make_agent("oracle-planner")
    observation = {
        "goal": np.int64(0),
        "gps": np.zeros(2, np.float32),
        "compass": np.zeros(1, np.float32),
        "oracle_map": np.zeros((13, 13, 2), np.uint8),
    }
    with pytest.raises(AgentError, match="maps.ego_size=601, maps.cell_size=0.1"):
        agent.act(observation)


def _lane_to_the_back() -> tuple[StartFrameGrid, np.ndarray, np.ndarray]:
    """Open floor ahead (x > -0.05 m), and behind it one lane one cell wide along y = 0: a
    grid, its passable cells and a distance field from the lane's far end."""
    grid = StartFrameGrid(61, 0.1)
    xy = grid.to_xy(*np.mgrid[0:61, 0:61])
    passable = ((xy[..., 0] > -0.05) | (np.abs(xy[..., 1]) < 0.05)) & (np.abs(xy[..., 1]) < 0.65)
    field = distance_field(passable, (xy[..., 0] < -2.0) & passable, grid.cell_size)
    return grid, passable, field


def test_three_steps_enter_a_lane_that_one_or_two_steps_do_not() -> None:
    grid, passable, field = _lane_to_the_back()
    position, heading = np.array([0.0, -0.12]), math.radians(240)
    assert choose_action(grid, field, passable, position, heading) is None
    assert two_step_action(grid, field, passable, position, heading) is None
    assert steps_ahead(grid, field, passable, position, heading, 2) is None
    route = steps_ahead(grid, field, passable, position, heading, 3)
    assert route == [1, 6, 6]  # 30° to line up with the lane, then straight into it
    end = position.copy()
    for index in route:
        end = step_points(end, index * math.pi / 6)[-1]
    assert end[0] < -0.2 and abs(end[1]) < 0.05
    assert steps_ahead(grid, field, passable, position, heading, 3, refused={1}) != route


def test_a_heading_refused_from_here_is_not_chosen_again() -> None:
    grid, passable, field = _lane_to_the_back()
    position = np.array([0.5, 0.0])
    straight = choose_action(grid, field, passable, position, math.pi)
    assert straight == Action.MOVE_FORWARD  # facing the lane: straight on
    # the simulator refused that step (whatever the map says): turn to another heading
    assert choose_action(grid, field, passable, position, math.pi, refused={6}) != straight
