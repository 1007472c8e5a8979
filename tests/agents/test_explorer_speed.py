"""The explorer's fast paths (issue 23) give exactly what the code they replaced gave.

Each rewritten function is compared with its old version (kept in
``multion_agents.bench.explorer_reference``) on random inputs, and the two agents are run
side by side on the same observations. ``test_explorer_actions.py`` pins the actions themselves.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import ndimage

from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion_agents.baselines.explorer import ExplorerAgent, ExplorerSettings, _close
from multion_agents.baselines.mapping import (
    CameraModel,
    DepthProjector,
    SemanticMap,
    detect_goals,
    goal_shaped,
)
from multion_agents.baselines.navigation import (
    StartFrameGrid,
    bounding_box,
    choose_action,
    interpolate,
    interpolate_many,
)
from multion_agents.bench import explorer_reference as ref
from v2_episodes import v2_episode

SEEDS = st.integers(0, 2**32 - 1)
FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
# channel values round the detector's thresholds (off ≤ 3, on ≥ 105) and scene-like ones
LEVELS = np.array([0, 1, 3, 4, 9, 60, 104, 105, 106, 180, 254, 255], dtype=np.uint8)


def _image(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """A muted image with goal-like rectangles, greys and near misses painted on it."""
    image = rng.integers(60, 200, (height, width, 3), dtype=np.uint8)
    for _ in range(rng.integers(0, 12)):
        r, c = rng.integers(0, height), rng.integers(0, width)
        h, w = rng.integers(1, 9), rng.integers(1, 12)
        colour = rng.choice(LEVELS, 3)
        if rng.random() < 0.3:
            colour[:] = colour[0]  # balanced: white or grey or black
        image[r : r + h, c : c + w] = colour
    return image


@FUZZ
@given(SEEDS, st.sampled_from([(16, 16), (32, 48), (64, 64), (33, 17)]))
def test_goal_detection_matches_the_old_code(seed: int, shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(seed)
    image = _image(rng, *shape)
    depth = rng.uniform(0.0, 1.0, (*shape, 1)).astype(np.float32)
    old, new = ref.reference_detect_goals(image), detect_goals(image)
    assert _same_detections(old, new)
    assert _same_detections(
        ref.reference_goal_shaped(old, depth, CameraModel()), goal_shaped(new, depth, CameraModel())
    )


def _same_detections(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        np.array_equal(a[k][0], b[k][0]) and np.array_equal(a[k][1], b[k][1]) for k in a
    )


GRID = StartFrameGrid(41, 0.1)


def _field(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A distance-like field with inf patches, and passable cells."""
    field = np.hypot(*np.mgrid[-20:21, -20:21]) * 0.1 + rng.uniform(0, 0.3, (41, 41))
    field[rng.random((41, 41)) < 0.1] = np.inf
    passable = rng.random((41, 41)) > 0.15
    return field, passable


@FUZZ
@given(SEEDS, st.booleans())
def test_step_choice_matches_the_old_code(seed: int, snapped: bool) -> None:
    rng = np.random.default_rng(seed)
    field, passable = _field(rng)
    position = rng.uniform(-2.2, 2.2, 2)  # some steps leave the small grid
    heading = float(rng.integers(-12, 24)) * math.radians(30.0)
    if not snapped:
        heading += float(rng.uniform(0.01, 0.5))
    assert choose_action(GRID, field, passable, position, heading) == ref.reference_choose_action(
        GRID, field, passable, position, heading
    )
    points = rng.uniform(-2.2, 2.2, (12, 2))
    expected = [interpolate(GRID, field, p) for p in points]
    assert interpolate_many(GRID, field, points).tolist() == expected


@FUZZ
@given(SEEDS)
def test_map_updates_match_the_old_code(seed: int) -> None:
    """Frames of random depth from random poses: the same layers, the same "changed" answers,
    and the boxes and margin kept on the way are those of the layers."""
    rng = np.random.default_rng(seed)
    grid, camera = StartFrameGrid(81, 0.1), CameraModel()
    new_map, old_map = SemanticMap(grid), ref.ReferenceSemanticMap(grid)
    size = int(rng.choice([16, 32]))
    projector = DepthProjector((size, size), camera, int(rng.choice([1, 2])))
    old_projector = ref.ReferenceDepthProjector((size, size), camera, projector.stride)
    pose: tuple[np.ndarray, float] | None = None
    for _ in range(int(rng.integers(1, 8))):
        depth = rng.choice([0.0, 0.02, rng.uniform(), 1.0], (size, size, 1)).astype(np.float32)
        depth = np.where(rng.random((size, size, 1)) < 0.5, depth, rng.uniform(size=(1, size, 1)))
        depth = depth.astype(np.float32)
        rows, cols = np.nonzero(rng.random((size, size)) < 0.05)
        detections = {int(rng.integers(0, 8)): (rows, cols)} if len(rows) else {}
        if rng.random() < 0.3:  # a surface nearer than 0.5 m in every column: nothing carved
            depth[0, :, 0] = 0.0
        if pose is None or rng.random() < 0.6:  # or the same pose again: fewer new cells
            pose = rng.uniform(-3.0, 3.0, 2), float(rng.uniform(-math.pi, math.pi))
        position, heading = pose
        for a, b in zip(
            projector.points(depth, position, heading),
            old_projector.points(depth, position, heading),
            strict=True,
        ):
            assert np.array_equal(a, b)
        placed = new_map.integrate(projector, depth, detections, position, heading)
        assert placed == old_map.integrate(old_projector, depth, detections, position, heading)
        assert new_map.changed == old_map.changed
        new_map.mark_free_disc(position, 0.15)
        old_map.mark_free_disc(position, 0.15)
        assert np.array_equal(new_map.obstacle, old_map.obstacle)
        assert np.array_equal(new_map.free, old_map.free)
    assert new_map.obstacle_extent.box(3, grid.size) == bounding_box(new_map.obstacle, 3)
    assert new_map.explored_extent.box(0, grid.size) == bounding_box(new_map.explored(), 0)
    assert np.array_equal(new_map.obstacle_grown, ndimage.binary_dilation(new_map.obstacle))


@pytest.mark.parametrize("map_type", [SemanticMap, ref.ReferenceSemanticMap])
def test_the_map_changes_when_floor_alone_is_new_and_not_when_a_frame_repeats(
    map_type: type[SemanticMap],
) -> None:
    camera, size = CameraModel(), 32
    projector = DepthProjector((size, size), camera, 1)
    # flat floor below the horizon, nothing above it, and a surface nearer than 0.5 m at the
    # top of every column, so nothing is carved: only floor cells are new
    depth = np.ones((size, size, 1), dtype=np.float32)
    below = projector.up[:, 0] < -0.3
    floor_z = -camera.height / projector.up[below, 0]
    depth[below, :, 0] = ((floor_z - camera.min_depth) / (camera.max_depth - camera.min_depth))[
        :, None
    ]
    depth[0, :, 0] = 0.0
    layers = map_type(StartFrameGrid(81, 0.1))
    position = np.zeros(2)
    layers.integrate(projector, depth, {}, position, 0.0)
    assert layers.changed and layers.free.any() and not layers.obstacle.any()
    layers.integrate(projector, depth, {}, position, 0.0)
    assert not layers.changed


def _twins(rng: np.random.Generator) -> tuple[ExplorerAgent, ref.ReferenceExplorerAgent]:
    """A fast and a reference explorer on a small map in the same random state."""
    small = ExplorerSettings(map_size=61)
    fast, old = ExplorerAgent(settings=small), ref.ReferenceExplorerAgent(settings=small)
    blobs = ndimage.binary_dilation(rng.random((61, 61)) < 0.03, iterations=2)
    walls = ndimage.binary_dilation(rng.random((61, 61)) < 0.02)
    for layer, mask in ((fast.map.free, blobs & ~walls), (fast.map.obstacle, walls & blobs)):
        mask[: int(rng.integers(0, 30))] = False  # often not touching the edges
        if mask.any():
            fast.map._add(*fast.grid.to_xy(*np.nonzero(mask)).T, layer)
    old.map.free[:], old.map.obstacle[:] = fast.map.free, fast.map.obstacle
    for name in ("_blocked", "_visited", "_given_up", "_around_path"):
        mask = rng.random((61, 61)) < rng.choice([0.0, 0.01, 0.1])
        getattr(fast, name)[:] = mask
        getattr(old, name)[:] = mask
    fast._tight = old._tight = int(rng.choice([0, 5]))
    return fast, old


@FUZZ
@given(SEEDS)
def test_passable_cells_frontiers_and_plans_match_the_old_code(seed: int) -> None:
    rng = np.random.default_rng(seed)
    fast, old = _twins(rng)
    fast._refresh_passable()
    old._refresh_passable()
    assert np.array_equal(fast._passable, old._passable)
    assert np.array_equal(fast._frontier(fast._passable), old._frontier(old._passable))
    position = rng.uniform(-3.0, 3.0, 2)  # near the edges of the small map too
    if rng.random() < 0.5:
        target = rng.uniform(-3.0, 3.0, 2)
        for agent in (fast, old):
            agent._target, agent._target_point = ("goal", 0), target.copy()
    for agent in (fast, old):
        agent._plan(position)
    assert fast._aim == old._aim and fast._tight == old._tight
    assert fast._field is not None and old._field is not None
    assert np.array_equal(fast._field, old._field)
    for radius in (0.15, 0.5, 0.6, 1.0):
        assert np.array_equal(fast.discs.disc(position, radius), old._disc(position, radius))
        expected = bounding_box(old._disc(position, radius), 0)
        if old._disc(position, radius).any():
            assert fast.discs.box(position, radius) == expected
    fast.discs.paint(fast._given_up, position, 1.0, True)
    old._give_up_near(position)
    assert np.array_equal(fast._given_up, old._given_up)
    end = position + rng.uniform(-1.0, 1.0, 2)
    assert fast._straight_and_free(position, end) == old._straight_and_free(position, end)


@FUZZ
@given(st.lists(st.floats(-50, 50), min_size=4, max_size=4), st.floats(0, 2e-4))
def test_still_means_what_allclose_says(values: list[float], nudge: float) -> None:
    a, b = np.array(values[:2]), np.array(values[2:])
    assert _close(a, b) == np.allclose(a, b, atol=1e-4)
    assert _close(a, a + nudge) == np.allclose(a, a + nudge, atol=1e-4)


def test_fast_and_reference_explorers_act_alike_on_a_val_episode() -> None:
    """Side by side on the same observations (what ``multion bench --only explorer`` times):
    the same action every step, and the same map at the end."""
    episode = v2_episode("val-2-on-00010")
    fast, old = ExplorerAgent(), ref.ReferenceExplorerAgent()
    config = EnvConfig(
        task=TaskConfig(num_goals=2, max_steps=400),
        camera=CameraConfig(width=64, height=64),
        sensors=tuple(dict.fromkeys([*fast.sensors, "gps"])),
    )
    env = MultiONEnv(config, episodes=[episode])
    try:
        observation, _ = env.reset(options={"episode_id": episode.episode_id})
        done, step = False, 0
        while not done:
            seen = {k: v for k, v in observation.items() if k in fast.sensors}
            action = fast.act(seen)
            assert action == old.act(seen), f"step {step}"
            observation, _, terminated, truncated, _ = env.step(action)
            done, step = terminated or truncated, step + 1
    finally:
        env.close()
    assert np.array_equal(fast.map.obstacle, old.map.obstacle)
    assert np.array_equal(fast.map.free, old.map.free)
    assert fast.times.steps == step and fast.times.mapping > 0 and fast.times.planning > 0


def test_the_explorer_bench_times_both_agents_and_stops_on_a_different_action(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from multion_agents.bench.explorer import run_explorer_bench

    results = run_explorer_bench(image=64, houses=1, steps=30)
    assert results["steps"] == 30
    for part in ("mapping", "planning", "rest", "total"):
        assert results[f"reference_{part}_ms"] > 0 and results[f"fast_{part}_ms"] > 0
    total = results["reference_total_ms"] / results["fast_total_ms"]
    assert results["ratio_total"] == pytest.approx(total)
    printed = capsys.readouterr().out
    assert "reference" in printed and "load average" in printed and results["env_step_ms"] > 0
    # a fast path that changed a decision makes the figures worthless: the bench says so
    monkeypatch.setattr(ref.ReferenceExplorerAgent, "act", lambda self, observation: 1)
    with pytest.raises(RuntimeError, match="changed a decision"):
        run_explorer_bench(image=64, houses=1, steps=30)
