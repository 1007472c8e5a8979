"""Episodes the agent's own moves can play (datasets version 3): a start with a possible step
(`can_step`) and every goal within reach of 0.25 m steps and 30° turns (`steps_reach_goals`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multion.config.task import EnvConfig, EpisodeConstraints, TaskConfig
from multion.scenes.registry import scene_ids
from multion.sim.geodesic import distance_field
from multion.sim.navgrid import NavGrid
from multion.sim.simulator import Simulator
from multion.task.env import MultiONEnv
from multion.task.sampling import can_step, iter_chunks, sample_episode
from multion.task.step_reach import steps_reach_goals
from v2_episodes import v2_episode

IMMOBILE = "val-1-on-00261"  # version 2: no step in any heading
POCKET = "val-1-on-00698"  # version 2: steps possible, the goal out of their reach
WALLED_IN = "val-1-on-00654"  # version 2: no step, in the same house as the pocket
VAL_SEED = 1  # scripts/make_datasets.py's val seed


def corridor_grid() -> NavGrid:
    """Two 1 m rooms joined by a 2 m corridor one cell (5 cm) wide along x."""
    cell = 0.05
    navigable = np.zeros((20, 80), dtype=bool)
    navigable[:, :20] = navigable[:, 60:] = True
    navigable[10, 20:60] = True  # row 10: y = 0.525, the corridor's centre line
    full = np.ones_like(navigable)
    return NavGrid((0.0, 0.0), cell, 0.0, full, navigable, navigable, ~full)


@pytest.mark.parametrize(("yaw_deg", "reached"), [(0.0, True), (180.0, True), (15.0, False)])
def test_a_gap_the_grid_passes_but_no_heading_enters(yaw_deg: float, reached: bool) -> None:
    grid = corridor_grid()
    goal = distance_field(grid, np.array([3.5, 0.525]), 0.05)
    start = np.array([0.275, 0.525])  # on the corridor's line, 5 steps from its mouth
    assert np.isfinite(grid.lookup(goal, start))  # connected on the grid
    yaw = math.radians(yaw_deg)  # 180°: the agent turns round first (turns are free)
    assert steps_reach_goals(grid, start, yaw, [goal], 1.5) is reached
    # 4 cm off the line (out of the corridor's row) steps at 60° and -90° line up again
    # (y moves by 0.2165 - 0.25 m), found although the search merges nearby positions
    assert steps_reach_goals(grid, start + [0.0, 0.04], 0.0, [goal], 1.5)


def test_can_step_agrees_with_the_simulator() -> None:
    episodes = [v2_episode(IMMOBILE), v2_episode("val-1-on-00000")]
    env = MultiONEnv(EnvConfig(task=TaskConfig(num_goals=1), sensors=("gps",)), episodes=episodes)
    try:
        for episode in episodes:
            obs, _ = env.reset(options={"episode": episode})
            moved = False
            for _ in range(12):  # a step in every heading the agent can turn to
                obs, *_ = env.step(1)
                moved |= bool(np.any(np.abs(obs["gps"]) > 1e-6))
                obs, *_ = env.step(2)
            grid = env.sim.load_scene(episode.scene_id)
            start = np.asarray(episode.start_position[:2])
            assert can_step(grid, start, episode.start_yaw) == moved
            assert moved == (episode.episode_id != IMMOBILE)
    finally:
        env.close()


def test_a_pocket_start_is_refused_and_a_long_walk_never_leaves_it() -> None:
    episode = v2_episode(POCKET)
    config = EnvConfig(task=TaskConfig(num_goals=1, max_steps=3000), sensors=("gps",))
    env = MultiONEnv(config, episodes=[episode])
    try:
        env.reset(options={"episode": episode})
        grid = env.sim.grid
        assert grid is not None
        start = np.asarray(episode.start_position[:2])
        field = distance_field(grid, np.asarray(episode.goals[0].position[:2]), 0.05)
        assert can_step(grid, start, episode.start_yaw)
        assert not steps_reach_goals(grid, start, episode.start_yaw, [field], 1.5)
        # the simulator agrees: 2,500 random turns and steps never bring the goal within 1.5 m
        rng = np.random.default_rng(0)
        closest = math.inf
        for action in rng.choice([1, 1, 2, 3], size=2500):
            env.step(int(action))
            assert env.state is not None
            closest = min(closest, env.state.distance_to_goal)
        assert closest > 1.5
    finally:
        env.close()


def scene_of(number: int, scenes: int, count: int) -> tuple[int, int]:
    """The scene index of packaged episode ``number`` and the number of its scene's first."""
    first = 0
    for index, quota in iter_chunks(range(scenes), count):
        if first <= number < first + quota:
            return index, first
        first += quota
    raise AssertionError(f"no episode {number}")


def test_the_guards_change_only_refused_draws_of_the_version_2_stream() -> None:
    scenes = scene_ids("val")
    number = int(WALLED_IN.rsplit("-", 1)[1])  # the first refused draw of its house
    index, first = scene_of(number, len(scenes), 1000)
    unguarded = EpisodeConstraints(mobile_start=False, step_paths=False)  # version 2's sampler
    simulator = Simulator()
    try:
        grid = simulator.load_scene(scenes[index])
        streams = [np.random.default_rng([VAL_SEED, 1, index]) for _ in range(2)]
        for k in range(number - first + 1):
            plain = sample_episode(grid, scenes[index], 1, streams[0], WALLED_IN, unguarded)
            guarded = sample_episode(grid, scenes[index], 1, streams[1], WALLED_IN)
            assert plain is not None and guarded is not None
            if first + k < number:
                assert guarded == plain
        assert plain == v2_episode(WALLED_IN)  # version 2's stream, reproduced
        assert guarded.start_position != plain.start_position
        fields = [distance_field(grid, np.asarray(g.position[:2]), 0.05) for g in guarded.goals]
        start = np.asarray(guarded.start_position[:2])
        assert steps_reach_goals(grid, start, guarded.start_yaw, fields, 1.5)
    finally:
        simulator.close()


def test_the_best_first_search_agrees_with_the_breadth_first_reference() -> None:
    """Issue 30: the search that replaced the breadth-first one answers the same, on draws
    that pass and draws that fail (the pocket, goals behind it), also when it widens to layers
    at once (no greedy expansions) or after a few."""
    from multion_agents.bench.reset import breadth_first_reach

    simulator = Simulator()
    rng = np.random.default_rng(3)
    answers: list[bool] = []
    try:
        pocket = v2_episode(POCKET)
        cases = []
        grid = simulator.load_scene(pocket.scene_id)
        pocket_field = distance_field(grid, np.asarray(pocket.goals[0].position[:2]), 0.05)
        cases.append(
            (grid, np.asarray(pocket.start_position[:2]), pocket.start_yaw, [pocket_field])
        )
        for scene in scene_ids("val")[:2]:
            grid = simulator.load_scene(scene)
            rows, cols = np.nonzero(grid.navigable)
            cells = grid.cell_to_world(rows, cols)
            for _ in range(12):
                start = cells[rng.integers(len(cells))]
                goals = cells[rng.integers(len(cells), size=int(rng.integers(1, 4)))]
                fields = [distance_field(grid, g, 0.05) for g in goals]
                cases.append((grid, start, float(rng.uniform(-np.pi, np.pi)), fields))
        for grid, start, yaw, fields in cases:
            reference = breadth_first_reach(grid, start, yaw, fields, 1.5)
            for greedy in (3000, 5, 0):
                assert (
                    steps_reach_goals(grid, start, yaw, fields, 1.5, greedy_expansions=greedy)
                    is reference
                )
            answers.append(reference)
    finally:
        simulator.close()
    assert answers[0] is False and answers.count(True) >= 10  # both answers were exercised


def test_online_sampling_draws_the_packaged_episodes_again() -> None:
    """The faster sampler (best-first search, fields kept for the reset) draws exactly the
    episodes of the packaged dataset from its stream."""
    from multion.config.datasets import load_dataset, packaged_dataset_path
    from multion.sim.geodesic import FieldCache

    packaged = load_dataset(packaged_dataset_path(3, "val"), 3)
    scenes = scene_ids("val")
    simulator = Simulator()
    try:
        grid = simulator.load_scene(scenes[0])
        rng = np.random.default_rng([VAL_SEED, 3, 0])
        fields = FieldCache()
        for expected in packaged[:8]:
            episode = sample_episode(grid, scenes[0], 3, rng, expected.episode_id, fields=fields)
            assert episode == expected
            for goal in episode.goals:  # the reset finds each goal's field computed already
                cached = fields.get(grid, np.asarray(goal.position[:2]), 0.05)
                assert not cached.flags.writeable
                assert np.array_equal(
                    cached, distance_field(grid, np.asarray(goal.position[:2]), 0.05)
                )
    finally:
        simulator.close()
