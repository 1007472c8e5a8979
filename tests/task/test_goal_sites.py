"""Train episodes from goal sites (issue 44): the sites, the sampler's guarantees, its cache's
memory bound, and the online sampler kept selectable with the same episodes as before."""

from __future__ import annotations

import dataclasses
import gc
import json
from pathlib import Path

import numpy as np
import pytest

from multion.config.codec import env_config_from_dict
from multion.config.ranges import ConfigError
from multion.config.task import EnvConfig, EpisodeConstraints, TaskConfig
from multion.sim.geodesic import FieldCache, distance_field
from multion.sim.navgrid import NavGrid
from multion.sim.simulator import Simulator
from multion.task.env import MultiONEnv
from multion.task.goal_sites import (
    PROCESS_SITE_CACHE,
    GoalSites,
    SiteFieldCache,
    choose_sites,
    house_rooms,
    room_of,
    sample_site_episode,
)
from multion.task.memory import estimate_env_bytes, estimate_process_bytes, goal_sites_bytes
from multion.task.sampling import can_step
from multion.task.step_reach import steps_reach_goals

HOUSE = "house-00003"
GOLDEN = Path(__file__).resolve().parent.parent / "data" / "online_train_episodes.json"
RADIUS = 0.05


@pytest.fixture(scope="module")
def grid() -> NavGrid:
    simulator = Simulator()
    try:
        return simulator.load_scene(HOUSE)
    finally:
        simulator.close()


def _draw(
    sites: GoalSites, grid: NavGrid, seed: int, count: int, num_goals: int, distractors: int = 0
) -> list:
    rng = np.random.default_rng(seed)
    episodes = []
    for index in range(count):
        episode = sample_site_episode(
            sites, grid, HOUSE, num_goals, rng, f"e{index}", num_distractors=distractors
        )
        assert episode is not None
        episodes.append(episode)
    return episodes


def test_sites_are_seeded_by_the_house_alone_and_every_room_has_one(grid: NavGrid) -> None:
    rooms = house_rooms(HOUSE)
    sites = choose_sites(grid, rooms, 32, HOUSE)
    assert np.array_equal(sites, choose_sites(grid, rooms, 32, HOUSE))
    # asking for fewer sites gives the first ones: the set does not shift with the count
    assert np.array_equal(sites[:20], choose_sites(grid, rooms, 20, HOUSE))
    assert len(set(sites.tolist())) == 32
    rows, cols = np.nonzero(grid.navigable)
    cells = grid.cell_to_world(rows, cols)
    cell_rooms = room_of(rooms, cells)
    rooms_with_floor = set(cell_rooms[cell_rooms >= 0].tolist())
    assert len(rooms_with_floor) >= 8
    assert set(cell_rooms[sites].tolist()) >= rooms_with_floor
    # spread: the sites lie farther from each other than as many random cells do
    gaps = np.hypot(*(cells[sites][:, None] - cells[sites][None]).transpose(2, 0, 1))
    random = cells[np.random.default_rng(0).choice(len(cells), 32, replace=False)]
    random_gaps = np.hypot(*(random[:, None] - random[None]).transpose(2, 0, 1))
    np.fill_diagonal(gaps, np.inf)
    np.fill_diagonal(random_gaps, np.inf)
    assert gaps.min(axis=1).mean() > 1.3 * random_gaps.min(axis=1).mean()


@pytest.mark.parametrize(("num_goals", "distractors"), [(1, 0), (3, 0), (2, 3)])
def test_site_episodes_keep_the_online_samplers_guarantees(
    grid: NavGrid, num_goals: int, distractors: int
) -> None:
    sites = GoalSites(32, RADIUS, 2**30)
    constraints = EpisodeConstraints()
    for episode in _draw(sites, grid, 5, 12, num_goals, distractors):
        house = sites.house(HOUSE, grid)
        site_positions = {tuple(p) for p in house.site_xy.tolist()}
        start = np.asarray(episode.start_position[:2])
        fields = [distance_field(grid, np.asarray(g.position[:2]), RADIUS) for g in episode.goals]
        previous, legs = start, []
        for goal, field in zip(episode.goals, fields, strict=True):
            assert tuple(goal.position[:2]) in site_positions
            legs.append(float(grid.lookup(field, previous, outside=np.inf)))
            previous = np.asarray(goal.position[:2])
        # the legs as a fresh fast marching measures them, within the constraints
        assert legs == list(episode.geodesic_distances)
        assert all(constraints.min_geodesic <= d <= constraints.max_geodesic for d in legs)
        goal_xy = np.asarray([g.position[:2] for g in episode.goals])
        gaps = np.hypot(*(goal_xy[:, None] - goal_xy[None]).transpose(2, 0, 1))
        assert (gaps[~np.eye(num_goals, dtype=bool)] >= constraints.min_goal_separation).all()
        assert bool(grid.is_navigable(start))
        assert can_step(grid, start, episode.start_yaw)
        assert steps_reach_goals(grid, start, episode.start_yaw, fields, constraints.reach)
        categories = [g.category for g in (*episode.goals, *episode.distractors)]
        assert len(set(categories)) == num_goals + distractors
        for distractor in episode.distractors:
            away = np.hypot(*(goal_xy - np.asarray(distractor.position[:2])).T)
            assert (away >= constraints.min_distractor_separation).all()


def test_same_seed_same_episodes_whatever_the_cache_holds(grid: NavGrid) -> None:
    roomy = GoalSites(32, RADIUS, 2**30, SiteFieldCache())
    _draw(roomy, grid, 99, 5, 3)  # other fields cached first
    tight = GoalSites(32, RADIUS, 1, SiteFieldCache())  # its own cache: one field at a time
    assert _draw(roomy, grid, 7, 8, 3) == _draw(tight, grid, 7, 8, 3)
    assert _draw(roomy, grid, 7, 8, 3) != _draw(roomy, grid, 8, 8, 3)


def test_the_site_cache_stays_within_its_budget(grid: NavGrid) -> None:
    field_bytes = 8 * int(grid.navigable.sum())
    sites = GoalSites(32, RADIUS, 3 * field_bytes, SiteFieldCache())  # its only user
    held = []
    for seed in range(6):
        _draw(sites, grid, seed, 4, 3)
        held.append((sites.held_bytes, sites.fields_held))
        assert sites.held_bytes <= sites.budget_bytes
    assert max(count for _, count in held) == 3
    assert sites.marched > 3  # dropped fields were marched again when drawn
    # a field marched again is the same field
    house = sites.house(HOUSE, grid)
    first = sites.values(house, 0).copy()
    for site in range(1, 5):
        sites.values(house, site)
    assert np.array_equal(first, sites.values(house, 0))


def test_a_reset_reads_the_sites_fields_and_measures_what_the_episode_says() -> None:
    config = EnvConfig(
        task=TaskConfig(num_goals=3), split="train", sensors=("goal",), episodes_per_scene=4
    )
    assert config.task.train_sampler == "sites"  # the default since issue 44
    env = MultiONEnv(config)
    try:
        env.reset(seed=2)
        marched = env._goal_sites.marched
        env.reset()
        episode, grid = env.episode, env.sim.grid
        assert episode is not None and grid is not None and env.state is not None
        assert episode.episode_id.startswith("train-sites-")
        house = env._goal_sites.house(episode.scene_id, grid)
        assert {tuple(g.position[:2]) for g in episode.goals} <= {
            tuple(p) for p in house.site_xy.tolist()
        }
        assert env.state.optimal_distances == episode.geodesic_distances
        for goal, field in zip(episode.goals, env._fields, strict=True):
            fresh = distance_field(grid, np.asarray(goal.position[:2]), RADIUS)
            assert np.array_equal(field, fresh)
        assert env._goal_sites.marched <= marched + 3  # at most the new goals' fields
    finally:
        env.close()


@pytest.mark.parametrize("key", ["1-on seed 7", "3-on seed 11"])
def test_the_online_sampler_still_draws_the_episodes_it_drew_before_issue_44(key: str) -> None:
    golden = json.loads(GOLDEN.read_text())["episodes"][key]
    num_goals, seed = int(key[0]), int(key.rsplit(" ", 1)[1])
    config = EnvConfig(
        task=TaskConfig(num_goals=num_goals, train_sampler="online"),
        split="train",
        sensors=("goal",),
        episodes_per_scene=2,
    )
    env = MultiONEnv(config)
    try:
        drawn = []
        for reset_seed in (seed, None):
            env.reset(seed=reset_seed)
            assert env.episode is not None
            drawn.append(json.loads(json.dumps(env.episode.to_dict())))
    finally:
        env.close()
    assert drawn == golden


def test_the_sampler_and_the_site_count_are_checked_and_named() -> None:
    with pytest.raises(
        ConfigError, match=r"task.train_sampler = 'fixed' is not allowed: allowed one of 'sites'"
    ):
        TaskConfig(train_sampler="fixed")
    with pytest.raises(
        ConfigError, match=r"task.goal_sites = 8 is out of range: allowed an integer in \[16,"
    ):
        TaskConfig(goal_sites=8)
    with pytest.raises(ConfigError, match=r"task.goal_site_cache_mib = 0 is out of range"):
        TaskConfig(goal_site_cache_mib=0)
    # what `multion train --set task.train_sampler=online` passes
    config = env_config_from_dict({"split": "train", "task": {"train_sampler": "online"}})
    assert config.task.train_sampler == "online"


def test_field_cache_put_is_what_get_returns(grid: NavGrid) -> None:
    cache = FieldCache()
    target = np.array([1.0, 1.0])
    made = distance_field(grid, target, RADIUS) + 1.0  # a field get() would not march
    cache.put(grid, target, RADIUS, made)
    assert cache.get(grid, target, RADIUS) is made


def test_a_servers_memory_estimate_counts_the_site_cache_once_per_process() -> None:
    sites = EnvConfig(split="train", task=TaskConfig(goal_site_cache_mib=300))
    online = EnvConfig(
        split="train", task=TaskConfig(goal_site_cache_mib=300, train_sampler="online")
    )
    assert goal_sites_bytes(sites) == 300 * 2**20
    assert estimate_env_bytes(sites) == estimate_env_bytes(online)  # not per env
    for envs in (1, 16):
        extra = estimate_process_bytes(sites, envs) - estimate_process_bytes(online, envs)
        assert extra == 300 * 2**20
    val = EnvConfig(split="val", task=TaskConfig(goal_site_cache_mib=300))
    assert goal_sites_bytes(val) == goal_sites_bytes(online) == 0


def test_the_envs_of_a_process_share_one_cache_and_draw_the_same_episodes() -> None:
    config = EnvConfig(
        task=TaskConfig(num_goals=3), split="train", sensors=("goal",), episodes_per_scene=4
    )
    users, marched = PROCESS_SITE_CACHE.users, PROCESS_SITE_CACHE.marched
    first, second = MultiONEnv(config), MultiONEnv(config)
    try:
        first.reset(seed=5)
        second.reset(seed=5)
        assert first._goal_sites.cache is second._goal_sites.cache is PROCESS_SITE_CACHE
        assert PROCESS_SITE_CACHE.users == users + 2
        assert second.episode == first.episode  # drawn from a warm cache, the same episode
        assert first._goal_sites.marched == PROCESS_SITE_CACHE.marched - marched
        assert second._goal_sites.marched == 0  # it read the fields the first env marched
        for mine, theirs in zip(first._fields, second._fields, strict=True):
            assert np.array_equal(mine, theirs)
    finally:
        first.close()
        second.close()
    assert PROCESS_SITE_CACHE.users == users
    online = MultiONEnv(dataclasses.replace(config, task=TaskConfig(train_sampler="online")))
    try:
        online.reset(seed=5)
        assert PROCESS_SITE_CACHE.users == users  # an env not drawing from sites asks nothing
    finally:
        online.close()


def test_the_budget_is_the_largest_asked_and_the_last_user_frees_the_cache(
    grid: NavGrid,
) -> None:
    cache = SiteFieldCache()
    field_bytes = 8 * int(grid.navigable.sum())
    small = GoalSites(32, RADIUS, 2 * field_bytes, cache)
    large = GoalSites(32, RADIUS, 5 * field_bytes, cache)
    assert small.budget_bytes == large.budget_bytes == 5 * field_bytes
    house = small.house(HOUSE, grid)
    assert large.house(HOUSE, grid) is house
    for site in range(6):
        small.values(house, site)
    assert (cache.fields_held, cache.held_bytes) == (5, 5 * field_bytes)
    assert large.values(house, 5) is small.values(house, 5)
    assert large.marched == 0 and small.marched == 6
    large.close()  # the budget shrinks to the largest left, the oldest fields go
    assert (cache.budget_bytes, cache.fields_held, cache.held_bytes) == (
        2 * field_bytes,
        2,
        2 * field_bytes,
    )
    large.close()  # closing twice is harmless
    assert cache.users == 1
    del small  # a view garbage-collected unclosed leaves too
    gc.collect()
    assert (cache.users, cache.fields_held, cache.held_bytes, cache.budget_bytes) == (0, 0, 0, 0)
    with pytest.raises(ValueError, match="budget_bytes must be at least 1, got 0"):
        cache.join(0)


def test_a_grid_with_other_cells_gets_its_own_sites_and_fields(grid: NavGrid) -> None:
    cache = SiteFieldCache()
    sites = GoalSites(32, RADIUS, 2**30, cache)
    house = sites.house(HOUSE, grid)
    walled = grid.navigable.copy()
    walled[:, walled.shape[1] // 2] = False  # a wall through the middle of the house
    other_grid = dataclasses.replace(grid, navigable=walled)
    other = sites.house(HOUSE, other_grid)
    assert other is not house and other.grid is other_grid
    assert sites.house(HOUSE, grid) is house
    for site in range(3):
        fresh = distance_field(other_grid, other.site_xy[site], RADIUS)
        assert np.array_equal(other.full_field(sites.values(other, site)), fresh)
