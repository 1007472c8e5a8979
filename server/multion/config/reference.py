"""Where the defaults come from: the paper or the reference code, file and line.

The reference code is saimwani/multiON (the paper's code, on habitat-lab); paths below are in
that repository. ``GET /v1/spec`` answers this table as ``sources``, and docs/concepts/task.md's table
cites the same lines. Fields not listed are this project's own choices (the procedural houses,
the navigable grid, the renderer) and say so in their docstrings. The learned agents' GRU size
(768, ``ppo_multinav.yaml`` line 45) is cited in ``multion_agents.learned.policy``.
"""

from __future__ import annotations

REFERENCE_REPO = "saimwani/multiON"
REFERENCE_COMMIT = "2ba4d25678dff9a990dc5e98ad81fd8c0a1bf15c"
"""The commit whose lines are cited (the repository's HEAD when they were checked)."""

DEFAULT_SOURCES: dict[str, str] = {
    "task.success_distance": "reference: configs/tasks/multinav_mp3d.yaml line 33 "
    "(SUCCESS_DISTANCE: 1.5)",
    "task.max_steps": "reference: configs/tasks/multinav_mp3d.yaml line 2 "
    "(MAX_EPISODE_STEPS: 2500); paper §5",
    "task.goal_reward": "reference: habitat_baselines/config/multinav/ppo_multinav.yaml "
    "lines 20-21 (SUCCESS_REWARD, SUBSUCCESS_REWARD: 3.0); paper §4.3",
    "task.slack_reward": "reference: habitat_baselines/config/default.py line 54 "
    "(SLACK_REWARD: -0.01); paper §4.3",
    "agent.radius": "reference: configs/tasks/multinav_mp3d.yaml line 10 (RADIUS: 0.1); paper §3",
    "agent.forward_step": "reference: habitat/config/default.py line 276 "
    "(FORWARD_STEP_SIZE = 0.25); paper §3",
    "agent.turn_angle_deg": "reference: configs/tasks/multinav_mp3d.yaml line 4 "
    "(TURN_ANGLE: 30); paper §3",
    "camera.width": "reference: configs/tasks/multinav_mp3d.yaml lines 20, 25 (WIDTH: 256)",
    "camera.height": "reference: configs/tasks/multinav_mp3d.yaml lines 21, 26 (HEIGHT: 256)",
    "camera.hfov_deg": "reference: configs/tasks/multinav_mp3d.yaml lines 22, 27 (HFOV: 79)",
    "camera.sensor_height": "reference: configs/tasks/multinav_mp3d.yaml lines 23, 28 "
    "(POSITION: [0, 0.88, 0])",
    "camera.min_depth": "reference: habitat/config/default.py line 303 (MIN_DEPTH = 0.0), "
    "not changed by configs/tasks/multinav_mp3d.yaml",
    "camera.max_depth": "reference: habitat/config/default.py line 304 (MAX_DEPTH = 10.0); "
    "habitat_baselines/rl/ppo/policy.py line 318 multiplies depth by 10 to get metres",
    "camera.normalize_depth": "reference: habitat/config/default.py line 305 "
    "(NORMALIZE_DEPTH = True)",
    "maps.cell_size": "reference: habitat/core/env.py lines 214-233 (conv_grid: 300 cells over "
    "240.36 m, 0.801 m each); paper §4.2",
    "maps.ego_size": "reference: habitat/core/env.py lines 291-293 and 347-349 (the centre "
    "50 x 50 of a rotated 80 x 80 patch); habitat_baselines/rl/ppo/policy.py lines 412, 419 "
    "(MapCNN(50, ...)), 465-466 (.view(bs, 50, 50, -1))",
    "maps.goal_cells": "reference: habitat/core/env.py line 279 (grid_loc ± 1: a 3 x 3 patch)",
    "maps.view_distance": "paper's supplement (5 m)",
    "task.goal_set": "paper §3 (colours: 8 coloured cylinders); the supplement's 'Varying "
    "target object shapes' (shapes)",
    "task.shape_size": "paper's supplement (a horizontal length/diameter of 0.4 m)",
}
"""Config field → where its default comes from."""
