"""Sensors checked against geometry known by hand in ``room-6x4`` (walls at x = 0, 6; y = 0, 4)."""

import math

import numpy as np
import pytest

from multion.config.episode import Episode, Goal
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, MapConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion_client.constants import GOAL_CATEGORIES, MAP_FREE, MAP_OCCUPIED, MAP_UNKNOWN, Action


def env_at(start, yaw, goals, sensors, camera=CameraConfig(), maps=MapConfig()):
    episode = Episode(
        "s", "room-6x4", (*start, 0.0), yaw, tuple(Goal(c, (x, y, 0.0)) for c, (x, y) in goals)
    )
    config = EnvConfig(
        task=TaskConfig(num_goals=len(goals)), camera=camera, maps=maps, sensors=sensors
    )
    env = MultiONEnv(config, episodes=[episode])
    obs, _ = env.reset(seed=0)
    return env, obs


def test_depth_to_wall_within_2cm():
    # facing +x from x = 3: the wall is 3 m ahead; planar depth is 3 m across the image centre
    env, obs = env_at((3.0, 2.0), 0.0, [(0, (1.0, 1.0))], ("depth",))
    depth_m = 10.0 * obs["depth"][:, :, 0]  # [0, 10] m, normalised (reference default)
    assert obs["depth"].dtype == np.float32 and obs["depth"].shape == (256, 256, 1)
    assert depth_m[128, 128] == pytest.approx(3.0, abs=0.02)
    assert depth_m[100, 60] == pytest.approx(3.0, abs=0.02)  # planar depth, not ray length
    # turning right by 90° (3 turns) faces the y = 0 wall, 2 m away
    for _ in range(3):
        obs, *_ = env.step(3)
    depth_m = 10.0 * obs["depth"][:, :, 0]  # [0, 10] m, normalised (reference default)
    assert depth_m[128, 128] == pytest.approx(2.0, abs=0.02)


def test_depth_is_clipped_and_normalised():
    env, obs = env_at((0.3, 2.0), math.pi, [(0, (4.0, 2.0))], ("depth",))  # 0.3 m from a wall
    assert obs["depth"].min() >= 0.0 and obs["depth"].max() <= 1.0
    assert obs["depth"][128, 128, 0] == pytest.approx(0.03, abs=1e-4)  # 0.3 m of [0, 10] m
    # the range before issue 31, [0.5, 5] m: below 0.5 m is clipped to 0
    camera = CameraConfig(min_depth=0.5, max_depth=5.0)
    env, obs = env_at((0.3, 2.0), math.pi, [(0, (4.0, 2.0))], ("depth",), camera=camera)
    assert obs["depth"][128, 128, 0] == pytest.approx(0.0)
    # facing the far wall, 5.7 m away: within [0, 10] m, clipped to 1 in [0.5, 5] m
    env, obs = env_at((0.3, 2.0), 0.0, [(0, (4.0, 2.0))], ("depth",), camera=camera)
    assert obs["depth"][128, 128, 0] == pytest.approx(1.0)
    env, obs = env_at((0.3, 2.0), 0.0, [(0, (4.0, 2.0))], ("depth",))
    assert obs["depth"][128, 128, 0] == pytest.approx(0.57, abs=3e-3)


@pytest.mark.parametrize("category", range(8))
def test_goal_cylinder_colour_seen_from_one_metre(category):
    env, obs = env_at((2.0, 2.0), 0.0, [(category, (3.0, 2.0))], ("rgb",))
    # the cylinder (0.75 m tall, camera at 0.88 m) fills the centre column below the horizon
    patch = obs["rgb"][190:230, 124:132].reshape(-1, 3).astype(float).mean(axis=0)
    expected = {
        "red": (1, 0, 0),
        "green": (0, 1, 0),
        "blue": (0, 0, 1),
        "cyan": (0, 1, 1),
        "magenta": (1, 0, 1),
        "yellow": (1, 1, 0),
        "black": (0, 0, 0),
        "white": (1, 1, 1),
    }
    on = np.array(expected[GOAL_CATEGORIES[category]], dtype=bool)
    if on.any():
        assert (patch[on] > 120).all(), (GOAL_CATEGORIES[category], patch)
    assert (patch[~on] < 40).all(), (GOAL_CATEGORIES[category], patch)
    # and nothing of that colour at the far left of the image
    assert not np.allclose(obs["rgb"][200, 5].astype(float), patch, atol=30)


def test_goal_mask_marks_the_goal_pixels():
    env, obs = env_at((2.0, 2.0), 0.0, [(5, (3.0, 2.0))], ("goal_mask",))
    mask = obs["goal_mask"]
    assert mask.dtype == np.uint8 and set(np.unique(mask)) == {0, 6}
    assert mask[210, 128] == 6 and mask[210, 20] == 0


def test_goal_one_hot_gps_compass():
    env, obs = env_at(
        (1.0, 1.0), math.pi / 2, [(3, (1.0, 3.5))], ("goal", "goal_onehot", "gps", "compass")
    )
    assert obs["goal"] == 3 and obs["goal_onehot"].tolist() == [0, 0, 0, 1, 0, 0, 0, 0]
    obs, *_ = env.step(1)  # forward along +y, which is "ahead" in the start frame
    assert obs["gps"] == pytest.approx([0.25, 0.0], abs=1e-6)
    obs, *_ = env.step(2)  # turn left 30°
    assert obs["compass"][0] == pytest.approx(math.radians(30), abs=1e-6)


def test_oracle_map_is_egocentric_and_rotated():
    # coarse 0.5 m cells to make the room's cells easy to reason about
    maps = MapConfig(cell_size=0.5, ego_size=21, goal_cells=1)
    env, obs = env_at((1.0, 2.0), 0.0, [(2, (4.0, 2.0))], ("oracle_map",), maps=maps)
    occ, goal = obs["oracle_map"][..., 0], obs["oracle_map"][..., 1]
    c = 10
    assert occ[c, c] == MAP_FREE
    # the goal is 3 m ahead: 6 cells up from the centre, same column; category 2 → value 3
    assert goal[c - 6, c] == 3 and goal.sum() == 3
    # far away (beyond the walls) is unknown; the wall cells at x = 0 lie behind the agent
    assert occ[0, 0] == MAP_UNKNOWN
    assert occ[c + 2, c] in (MAP_OCCUPIED, MAP_FREE)
    # turning left 90° puts the goal on the agent's right: same row as the agent, to the right
    for _ in range(3):
        obs, *_ = env.step(2)
    assert obs["oracle_map"][c, c + 6, 1] == 3


def test_the_goal_never_vanishes_from_a_rotated_oracle_map():
    """Sampling a rotated crop cell by cell skips some map cells; a goal is one cell and used to
    vanish at some headings (10 % of poses near goals in the v3 val houses)."""
    maps = MapConfig(cell_size=0.8, ego_size=25, goal_cells=1)
    env, obs = env_at((1.0, 1.3), 0.0, [(4, (4.6, 2.9))], ("oracle_map",), maps=maps)
    oracle = env._oracle
    assert oracle is not None
    half = maps.ego_size // 2
    for degrees in range(0, 360, 3):
        yaw = math.radians(degrees)
        crop = oracle.egocentric(oracle.layers, env.sim.position, yaw)
        marked = np.argwhere(crop[..., 1] == 5)
        assert len(marked) == 1, f"goal cells in the crop at {degrees}°: {len(marked)}"
        # where it should be: the goal cell's centre, in the agent's frame
        row, col = oracle.coarse_cell(np.array([4.6, 2.9]))
        centre = oracle.grid.origin + (np.array([col, row]) + 0.5) * oracle.coarse_size
        dx, dy = centre - env.sim.position
        ahead = dx * math.cos(yaw) + dy * math.sin(yaw)
        left = -dx * math.sin(yaw) + dy * math.cos(yaw)
        expected = (half - round(ahead / 0.8), half - round(left / 0.8))
        assert tuple(marked[0]) == expected


def test_oracle_ego_map_is_occluded_by_walls():
    # an L-shaped view: in the empty room everything within 5 m in front is revealed, and the
    # cells behind the agent are not
    maps = MapConfig(cell_size=0.5, ego_size=21)
    env, obs = env_at(
        (1.0, 2.0), 0.0, [(2, (4.0, 2.0))], ("oracle_ego_map", "oracle_map"), maps=maps
    )
    ego, full = obs["oracle_ego_map"][..., 0], obs["oracle_map"][..., 0]
    c = 10
    assert ego[c - 4, c] == MAP_FREE  # 2 m ahead: seen
    assert (
        ego[
            c - 6,
            c + 0,
        ]
        == full[c - 6, c]
    )
    assert ego[c + 1, c] == MAP_UNKNOWN  # just behind the agent: not seen
    # cells beyond the far wall (x > 6) are never revealed, even within 5 m
    env2, obs2 = env_at((4.5, 2.0), 0.0, [(2, (1.0, 2.0))], ("oracle_ego_map",), maps=maps)
    assert (obs2["oracle_ego_map"][c - 5 : c - 3, c, 0] != MAP_FREE).all()


def test_seen_goals_are_recorded_for_the_supplement_table():
    # goal 2 (green) is in view from the start, before goal 1 (red, behind the agent) is found
    episode_goals = [(0, (0.5, 2.0)), (1, (4.5, 2.0))]
    env, _ = env_at((2.0, 2.0), 0.0, episode_goals, ("goal",))
    for action in [2] * 6 + [1] * 3 + [0]:  # turn around, walk to red, FOUND
        _, _, _, _, info = env.step(action)
    assert info["metrics"]["goals_found"] == 1
    assert info["metrics"]["seen_before_current"] == [True]


def test_hidden_goals_are_not_rendered_but_still_count():
    goals = [(5, (3.0, 2.0))]
    _, shown = env_at((2.0, 2.0), 0.0, goals, ("rgb", "goal_mask"))
    config = EnvConfig(
        task=TaskConfig(num_goals=1, goals_visible=False), sensors=("rgb", "goal_mask")
    )
    episode = Episode("s", "room-6x4", (2.0, 2.0, 0.0), 0.0, (Goal(5, (3.0, 2.0, 0.0)),))
    env = MultiONEnv(config, episodes=[episode])
    hidden, info = env.reset(seed=0)
    assert shown["goal_mask"][210, 128] == 6 and not hidden["goal_mask"].any()
    assert not np.array_equal(shown["rgb"][210, 128], hidden["rgb"][210, 128])  # floor, not yellow
    *_, info = env.step(Action.FOUND)  # 1 m away: still found
    assert info["metrics"]["success"] == 1.0


def test_oracle_map_crop_defaults_to_the_reference_50_cells_of_0_8_m():
    """saimwani/multiON habitat/core/env.py: 0.8 m cells (conv_grid, lines 214-233), the centre
    50 × 50 of a rotated 80 × 80 patch (lines 291-293, 347-349), goals as grid_loc ± 1 (279)."""
    assert MapConfig().ego_size == 50 and MapConfig().cell_size == 0.8
    assert MapConfig().goal_cells == 3
    env, obs = env_at((1.0, 2.0), 0.0, [(2, (4.0, 2.0))], ("oracle_map", "oracle_ego_map"))
    assert obs["oracle_map"].shape == (50, 50, 2) == obs["oracle_ego_map"].shape
    assert env.observation_space["oracle_map"].shape == (50, 50, 2)


def test_even_crop_puts_the_agent_in_cell_half_half_and_goals_as_3x3_squares():
    # the agent at cell (25, 25) of a 50-cell crop: 25 cells ahead (rows 0-24) and 24 behind,
    # as index 25 of the reference's patch[40-25:40+25] around the agent's index 40
    maps = MapConfig(cell_size=0.5, ego_size=50, goal_cells=3)
    env, obs = env_at((1.0, 2.0), 0.0, [(2, (4.0, 2.0))], ("oracle_map",), maps=maps)
    goal = obs["oracle_map"][..., 1]
    c = 25
    assert obs["oracle_map"][c, c, 0] == MAP_FREE
    # 3 m ahead = 6 cells up; the goal is a 3 × 3 square of value 3 around its cell
    rows, cols = np.nonzero(goal)
    assert (goal[rows, cols] == 3).all() and len(rows) == 9
    assert (rows.min(), rows.max(), cols.min(), cols.max()) == (c - 7, c - 5, c - 1, c + 1)
    assert goal[c - 6, c] == 3


def test_each_goal_keeps_its_own_cell_when_squares_overlap():
    maps = MapConfig(cell_size=0.5, ego_size=21, goal_cells=3)
    goals = [(2, (4.0, 2.0)), (5, (4.5, 2.0))]  # one cell apart: the squares overlap
    env, obs = env_at((1.0, 2.0), 0.0, goals, ("oracle_map",), maps=maps)
    goal, c = obs["oracle_map"][..., 1], 10
    assert goal[c - 6, c] == 3 and goal[c - 7, c] == 6


def test_goal_cells_must_be_odd():
    with pytest.raises(ValueError, match="maps.goal_cells must be odd"):
        MapConfig(goal_cells=2)
