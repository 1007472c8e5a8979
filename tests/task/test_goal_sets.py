"""Goal sets: the paper's coloured cylinders (default) and the supplement's red shapes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multion.config.episode import Episode, Goal
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, MapConfig, TaskConfig
from multion.sim.goal_shapes import SHAPES, goal_mesh
from multion.task.env import MultiONEnv
from multion_client.constants import (
    GOAL_CATEGORIES,
    GOAL_SETS,
    SHAPE_CATEGORIES,
    goal_categories,
)


def test_goal_sets_name_their_categories() -> None:
    assert TaskConfig().goal_set == "colours" and goal_categories() == GOAL_CATEGORIES
    assert goal_categories("shapes") == SHAPE_CATEGORIES == tuple(SHAPES)
    assert SHAPE_CATEGORIES == (
        "cone",
        "cube",
        "cylinder",
        "frustum",
        "joined_frustums",
        "sphere",
        "tetrahedron",
        "torus",
    )  # fmt: skip  (the supplement's order)
    assert all(len(names) == len(GOAL_CATEGORIES) for names in GOAL_SETS.values())
    with pytest.raises(ValueError, match="unknown goal set 'animals'"):
        goal_categories("animals")
    with pytest.raises(ValueError, match="task.goal_set"):
        TaskConfig(goal_set="animals")


@pytest.mark.parametrize("category", range(8))
def test_shape_meshes_are_closed_and_0_4_m_across(category: int) -> None:
    mesh = goal_mesh(category, 0.4, 0.6)
    triangles = mesh.indices.reshape(-1, 3)
    assert mesh.indices.min() >= 0 and mesh.indices.max() < len(mesh.vertices)
    # closed: every edge is shared by two triangles, once in each direction
    edges = {
        (int(a), int(b)) for t in triangles for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))
    }

    # (degenerate rings at a revolved apex repeat a vertex; compare positions, not indices)
    def key(i: int) -> tuple[float, ...]:
        return tuple(np.round(mesh.vertices[i], 9))

    directed = {(key(a), key(b)) for a, b in edges if key(a) != key(b)}
    assert all((b, a) in directed for a, b in directed)
    shape = mesh.vertices[mesh.vertices[:, 2] >= 0.6 - 1e-9]
    across = max(np.ptp(shape[:, 0]), np.ptp(shape[:, 1]))
    assert across == pytest.approx(0.4, abs=0.02)
    assert mesh.vertices[:, 2].min() == pytest.approx(0.0)


@pytest.mark.parametrize("category", range(8))
def test_shape_goals_are_red_and_in_the_goal_mask(category: int) -> None:
    episode = Episode("s", "room-6x4", (2.0, 2.0, 0.0), 0.0, (Goal(category, (3.2, 2.0, 0.0)),))
    task = TaskConfig(num_goals=1, goal_set="shapes")
    config = EnvConfig(
        task=task,
        camera=CameraConfig(width=96, height=96),
        maps=MapConfig(cell_size=0.5, ego_size=21),
        sensors=("rgb", "goal_mask", "oracle_map", "goal"),
    )
    env = MultiONEnv(config, episodes=[episode])
    obs, _ = env.reset(seed=0)
    env.close()
    goal = obs["goal_mask"] == category + 1
    assert goal.sum() > 100 and not (obs["goal_mask"] > 0)[~goal].any()
    pixels = obs["rgb"][goal].astype(int)
    assert (pixels[:, 0] > 100).all() and (pixels[:, 1:] == 0).all()  # pure red
    assert int(obs["goal"]) == category and (obs["oracle_map"][..., 1] == category + 1).any()


def test_the_same_episode_draws_either_set() -> None:
    episode = Episode("s", "room-6x4", (2.0, 2.0, 0.0), 0.0, (Goal(2, (3.2, 2.0, 0.0)),))
    images = {}
    for goal_set in GOAL_SETS:
        config = EnvConfig(
            task=TaskConfig(num_goals=1, goal_set=goal_set),
            camera=CameraConfig(width=96, height=96),
            sensors=("rgb", "goal_mask"),
        )
        env = MultiONEnv(config, episodes=[episode])
        obs, _ = env.reset(seed=0)
        env.close()
        images[goal_set] = obs
    colours, shapes = images["colours"], images["shapes"]
    blue = colours["rgb"][colours["goal_mask"] == 3].astype(int)
    assert (blue[:, 2] > 100).all() and (blue[:, :2] == 0).all()  # category 2: a blue cylinder
    assert (shapes["goal_mask"] == 3).sum() > (colours["goal_mask"] == 3).sum()  # a bigger shape


@pytest.mark.parametrize("renderer", ["tiny", "egl"])
def test_both_renderers_draw_every_shape_alike(renderer: str) -> None:
    # the EGL plugin draws meshes from files only: the shapes are OBJ files (goal_mesh_file)
    from multion.sim.camera import egl_plugin_loads

    if renderer == "egl" and not egl_plugin_loads():
        pytest.skip("the EGL plugin does not load here")
    goals = tuple(Goal(c, (0.7 + 0.6 * c, 3.4, 0.0)) for c in range(8))
    episode = Episode("s", "room-6x4", (3.0, 0.6, 0.0), math.pi / 2, goals)
    config = EnvConfig(
        task=TaskConfig(num_goals=8, goal_set="shapes"),
        camera=CameraConfig(width=128, height=128, renderer=renderer, hfov_deg=120.0),
        sensors=("rgb", "goal_mask"),
    )
    env = MultiONEnv(config, episodes=[episode])
    obs, _ = env.reset(seed=0)
    env.close()
    counts = [int((obs["goal_mask"] == c + 1).sum()) for c in range(8)]
    assert min(counts) > 10, counts
