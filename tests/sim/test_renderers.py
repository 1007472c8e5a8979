"""TinyRenderer and the EGL plugin render the same poses alike: depth within a small tolerance,
``goal_mask`` equal up to edge pixels, RGB close; ``auto`` and ``egl`` fail or fall back clearly.

EGL tests skip with a message naming the packages where the plugin does not load; CI installs
Mesa's EGL and sets ``MULTION_REQUIRE_EGL=1``, which turns those skips into failures (the
``egl`` fixture, ``tests/sim/conftest.py``). Houses: ``tests/sim/test_merged_visual.py``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import ndimage

from multion.config.episode import Episode, Goal
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.sim import camera as camera_module
from multion.sim.camera import RendererUnavailableError
from multion.sim.simulator import Simulator
from multion.task.env import MultiONEnv
from multion.task.generate import generate_episodes

SIZE = 64
HOUSE = "house-00061"


def _episode() -> Episode:
    """Two goals in the empty 6 × 4 room, in front of the start, at different distances."""
    return Episode(
        episode_id="render-0",
        scene_id="room-6x4",
        start_position=(0.8, 2.0, 0.0),
        start_yaw=0.0,
        goals=(Goal(0, (3.0, 1.6, 0.0)), Goal(3, (4.5, 2.8, 0.0))),
    )


def _house_episode() -> Episode:
    """house-00061 (scene generator v2, ~500 boxes): a generated 3-ON episode whose start is
    moved to a navigable point 1.5–3 m from its first goal, in sight of it and facing it."""
    episode = generate_episodes(3, "val", 1, seed=0, scenes=[HOUSE], progress=False)[0]
    grid = Simulator().load_scene(HOUSE)
    goal = np.array(episode.goals[0].position[:2])
    rows, cols = np.nonzero(grid.navigable)
    points = grid.cell_to_world(rows, cols)
    distance = np.linalg.norm(points - goal, axis=1)
    for k in np.argsort(np.abs(distance - 2.2)):
        start = points[k]
        if not 1.5 <= distance[k] <= 3.0:
            break
        line = start + np.linspace(0, 1, 40)[:, None] * (goal - start)
        if not grid.lookup(grid.view_blocked, line, outside=True).any():
            yaw = float(np.arctan2(*(goal - start)[::-1]))
            return dataclasses.replace(
                episode, start_position=(*map(float, start), 0.0), start_yaw=yaw
            )
    raise AssertionError("no point in sight of the goal")


def _observations(
    renderer: str, actions: list[int], episode: Episode | None = None
) -> tuple[list[dict], str | None]:
    episode = episode or _episode()
    config = EnvConfig(
        task=TaskConfig(num_goals=len(episode.goals)),
        camera=CameraConfig(width=SIZE, height=SIZE, renderer=renderer),
        sensors=("rgb", "depth", "goal_mask"),
    )
    env = MultiONEnv(config, episodes=[episode])
    try:
        observation, _ = env.reset(seed=0)
        frames = [observation]
        for action in actions:
            frames.append(env.step(action)[0])
        return frames, env.sim.renderer
    finally:
        env.close()


def _depth_edges(depth: np.ndarray, jump: float = 0.02) -> np.ndarray:
    """Pixels within two pixels of a depth jump larger than ``jump`` (9 cm) between neighbours."""
    return _edges(
        np.zeros(depth.shape),
        np.abs(np.diff(depth, axis=0)) > jump,
        np.abs(np.diff(depth, axis=1)) > jump,
    )


def _edges(mask: np.ndarray, rows: np.ndarray | None = None, cols: np.ndarray | None = None):
    """Pixels within two pixels of a label boundary."""
    rows = mask[:-1] != mask[1:] if rows is None else rows
    cols = mask[:, :-1] != mask[:, 1:] if cols is None else cols
    boundary = np.zeros(mask.shape, dtype=bool)
    boundary[:-1] |= rows
    boundary[1:] |= rows
    boundary[:, :-1] |= cols
    boundary[:, 1:] |= cols
    return ndimage.binary_dilation(boundary, iterations=1)


def test_egl_and_tiny_agree_on_the_same_poses(egl: None) -> None:
    actions = [1, 1, 2, 1, 3, 3, 1]  # forward, a left turn, right turns: both goals in and out
    tiny, used_tiny = _observations("tiny", actions)
    hardware, used_egl = _observations("egl", actions)
    assert (used_tiny, used_egl) == ("tiny", "egl")
    assert _agree(tiny, hardware) >= 3  # the masks compared were not all empty


def test_egl_and_tiny_agree_in_a_house(egl: None) -> None:
    """The same checks in a v2 house, which EGL draws as one merged mesh (TinyRenderer: a body
    per box), with the goals in view at the start."""
    actions = [2, 2, 3, 3, 3, 3, 2, 2, 1, 1, 1, 3, 3, 3, 1, 1]
    tiny, _ = _observations("tiny", actions, _house_episode())
    hardware, _ = _observations("egl", actions, _house_episode())
    assert _agree(tiny, hardware) >= 2


def _agree(tiny: list[dict], hardware: list[dict]) -> int:
    """Asserts every pair of frames agrees; returns how many showed a goal."""
    goals_seen = 0
    for a, b in zip(tiny, hardware, strict=True):
        depth = np.abs(a["depth"] - b["depth"])[..., 0]
        assert np.median(depth) < 0.002  # of 4.5 m: under a centimetre
        # away from depth discontinuities (silhouettes), every pixel agrees within 4.5 cm
        assert (depth[~_depth_edges(a["depth"][..., 0])] < 0.01).all()
        mask_a, mask_b = a["goal_mask"], b["goal_mask"]
        assert not ((mask_a != mask_b) & ~_edges(mask_a)).any()
        goals_seen += int(mask_a.any())
        # the two renderers light surfaces differently (TinyRenderer's ambient/diffuse
        # coefficients, OpenGL's own light): colours are close, not equal
        rgb_a, rgb_b = a["rgb"].astype(float), b["rgb"].astype(float)
        assert np.abs(rgb_a - rgb_b).mean() < 40
        assert np.abs(rgb_a.mean((0, 1)) - rgb_b.mean((0, 1))).max() < 30
    return goals_seen


def test_egl_is_deterministic(egl: None) -> None:
    first, _ = _observations("egl", [1, 2])
    second, _ = _observations("egl", [1, 2])
    for a, b in zip(first, second, strict=True):
        for key in a:
            assert np.array_equal(a[key], b[key]), key


def test_auto_falls_back_to_tiny_and_egl_names_the_packages(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(camera_module, "_egl_failed", False)
    monkeypatch.setattr(camera_module, "_egl_loaded", False)  # as in a fresh process
    monkeypatch.setattr(camera_module, "egl_plugin_path", lambda: None)  # a pybullet without it
    # and no OpenGL context either (the gl renderer's fallback: tests/sim/test_gl_renderer.py)
    monkeypatch.setattr(camera_module, "gl_unavailable_reason", lambda: "no EGL here")
    _, used = _observations("auto", [1])
    assert used == "tiny"
    assert camera_module.resolve_renderer("auto") == "tiny"
    with pytest.raises(RendererUnavailableError, match="libegl-mesa0"):
        _observations("egl", [])


def test_an_unknown_renderer_is_refused_naming_the_choices() -> None:
    with pytest.raises(ValueError, match="camera.renderer.*tiny.*egl.*auto"):
        CameraConfig(renderer="vulkan")
