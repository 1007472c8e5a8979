"""Real-object goals (``task.goal_set = "objects"``): everyday models from ``pybullet_data``,
upright on the floor, 0.3-0.9 m, at a yaw fixed by the episode, visible, never blocking."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pybullet_data
import pytest

from multion.config.episode import Episode, Goal
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, MapConfig, TaskConfig
from multion.scenes.registry import layout_for
from multion.sim import goal_objects
from multion.sim.camera import egl_plugin_loads
from multion.sim.goal_objects import MODELS, body_bounds, goal_yaw, scaled_urdf
from multion.sim.world import PyBulletWorld
from multion.task.env import MultiONEnv
from multion_client.constants import OBJECT_CATEGORIES, goal_categories

EXCLUDED = ("duck", "bunny", "bicycle", "domino", "laikago")
"""Models with terms of their own (the duck's, Stanford's, CC BY-SA, own licence files)."""


def test_the_sets_and_their_models() -> None:
    assert goal_categories("objects") == OBJECT_CATEGORIES and len(OBJECT_CATEGORIES) == 8
    train, test = goal_categories("unseen_train"), goal_categories("unseen_test")
    assert len(train) == len(test) == 8 and not set(train) & set(test)
    assert {MODELS[n].urdf for n in train}.isdisjoint(MODELS[n].urdf for n in test)
    root = Path(pybullet_data.getDataPath())
    for name, model in MODELS.items():
        assert (root / model.urdf).is_file(), name
        assert not any(word in model.urdf for word in EXCLUDED), name
        assert 0.3 <= model.size <= 0.9
    assert goal_yaw("ep-1", 0) == goal_yaw("ep-1", 0) != goal_yaw("ep-1", 1)
    assert 0.0 <= goal_yaw("ep-2", 3) < 2 * math.pi


def test_objects_stand_on_the_floor_at_their_size_and_block_nothing() -> None:
    world = PyBulletWorld.from_layout(layout_for("room-6x4"))
    try:
        goals = [((1.0 + 0.6 * c, 2.0, 0.0), c, 0.3 * c) for c in range(8)]
        bodies = world.place_object_goals(goals)
        for body, ((x, y, _), category, _) in zip(bodies, goals, strict=True):
            low, high = body_bounds(body, world.client)
            assert low[2] == pytest.approx(0.0, abs=0.01), OBJECT_CATEGORIES[category]
            # centred on its goal point whatever its yaw (PyBullet moves bodies by their centre
            # of mass, which some models have off centre)
            assert (low[:2] + high[:2]) / 2 == pytest.approx((x, y), abs=0.08)
            # its largest extent is its size (a turned footprint's box is up to sqrt(2) wider)
            size = MODELS[OBJECT_CATEGORIES[category]].size
            assert high[2] - low[2] <= size + 0.01
            assert 0.9 * size <= max(high - low) <= math.sqrt(2) * size + 0.01  # hull margins
            # visual only: a ray through the object, above the floor, hits nothing before the wall
            hit, fraction, _ = world.cast_rays(
                np.array([[x, y - 0.5, 0.1]]), np.array([[x, y + 0.5, 0.1]])
            )
            assert not hit[0], OBJECT_CATEGORIES[category]
        # placed again (next episode): the same bodies are reused, not new ones
        assert world.place_object_goals(goals) == bodies
    finally:
        world.close()


def scene(goal_set: str, episode_id: str = "o", renderer: str = "tiny") -> dict[str, np.ndarray]:
    goals = tuple(Goal(c, (0.7 + 0.6 * c, 3.4, 0.0)) for c in range(8))
    episode = Episode(episode_id, "room-6x4", (3.0, 0.6, 0.0), math.pi / 2, goals)
    config = EnvConfig(
        task=TaskConfig(num_goals=8, goal_set=goal_set),
        camera=CameraConfig(width=128, height=128, hfov_deg=120.0, renderer=renderer),
        maps=MapConfig(cell_size=0.5, ego_size=21),
        sensors=("rgb", "goal_mask", "oracle_map"),
    )
    env = MultiONEnv(config, episodes=[episode])
    try:
        obs, _ = env.reset(seed=0)
    finally:
        env.close()
    return obs


def test_every_object_is_seen_and_masked_with_its_category() -> None:
    obs = scene("objects")
    counts = [int((obs["goal_mask"] == c + 1).sum()) for c in range(8)]
    assert min(counts) > 10, counts
    # the oracle map marks them like cylinders: category + 1
    assert set(np.unique(obs["oracle_map"][..., 1])) - {0} <= set(range(1, 9))
    # they look like objects, not one flat colour: textures and several materials
    colours = {tuple(px) for px in obs["rgb"][obs["goal_mask"] > 0][::7]}
    assert len(colours) > 20


def test_yaw_is_reproducible_and_comes_from_the_episode() -> None:
    first, again, other = scene("objects", "a"), scene("objects", "a"), scene("objects", "b")
    assert np.array_equal(first["rgb"], again["rgb"])
    assert not np.array_equal(first["goal_mask"], other["goal_mask"])


def test_unseen_objects_are_drawn_and_differ_between_train_and_test() -> None:
    train, test = scene("unseen_train"), scene("unseen_test")
    for obs in (train, test):  # flat random shapes, 3 m away in a 128-pixel, 120-degree view
        counts = [int((obs["goal_mask"] == c + 1).sum()) for c in range(8)]
        assert min(counts) > 2, counts
    assert not np.array_equal(train["rgb"], test["rgb"])


@pytest.mark.skipif(not egl_plugin_loads(), reason="the EGL plugin does not load here")
def test_egl_draws_the_objects_at_the_same_size() -> None:
    # the EGL plugin keeps the first size it draws of a mesh file: the models are scaled in
    # their URDF copies, never by loadURDF's globalScaling (which it ignores)
    egl, tiny = scene("objects", renderer="egl"), scene("objects")
    for c in range(8):
        a, b = int((egl["goal_mask"] == c + 1).sum()), int((tiny["goal_mask"] == c + 1).sum())
        assert a > 10 and abs(a - b) <= max(6, 0.3 * b), (OBJECT_CATEGORIES[c], a, b)


def test_two_pybullet_data_installs_never_share_a_scaled_urdf(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A scaled URDF names its meshes by absolute path: one written by another install (another
    virtualenv, since removed) must not be read by this one."""
    model = next(m for m in MODELS.values() if m.urdf.startswith("random_urdfs/"))
    cache = tmp_path / "cache"
    mine = scaled_urdf(model, cache)
    other = tmp_path / "other-install"
    folder = Path(model.urdf).parent
    shutil.copytree(Path(pybullet_data.getDataPath()) / folder, other / folder)
    monkeypatch.setattr(goal_objects.pybullet_data, "getDataPath", lambda: str(other))
    theirs = scaled_urdf(model, cache)
    assert theirs != mine
    assert str(other) in theirs.read_text() and str(other) not in mine.read_text()
