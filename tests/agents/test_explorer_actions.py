"""The explorer's decisions are pinned: its actions on a fixed set of val episodes (issue 23).

Its mapping and planning were made faster without changing a single decision; these action
sequences were recorded with the code before that work, so any change to what the explorer does
(on purpose or not) fails here. To record them again after a deliberate change of behaviour:
``python tests/agents/test_explorer_actions.py`` (and say why in the commit).
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import numpy as np
import pytest

from multion.config.codec import env_config_to_dict
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion_agents.registry import make_agent
from v2_episodes import v2_episode

DATA = Path(__file__).parent / "data" / "explorer_actions.json"
CASES = (
    # (episode, image size, step cap), all played to their end: goal memory and FOUND calls, a
    # white plant pot taken for a goal by colour, frontiers given up, a margin that walls the
    # agent in (planning without it for a while), a goal seen over a box
    ("val-3-on-00250", 128, 300),
    ("val-3-on-00003", 128, 520),
    ("val-1-on-00650", 256, 460),
    ("val-1-on-00000", 256, 250),
)


def play(
    episode_id: str, image: int, max_steps: int, depth: tuple[float, float] | None = None
) -> dict[str, object]:
    """The explorer's actions on one (version 2) val episode, and digests of its final map.
    ``depth``: the sensor's (min, max) depth, metres (None: the default, [0, 10] m)."""
    episode = v2_episode(episode_id)
    num_goals = episode.num_goals
    agent = make_agent("explorer", seed=0)
    camera = CameraConfig(width=image, height=image)
    if depth is not None:
        camera = CameraConfig(width=image, height=image, min_depth=depth[0], max_depth=depth[1])
    config = EnvConfig(
        task=TaskConfig(num_goals=num_goals, max_steps=max_steps),
        camera=camera,
        sensors=tuple(dict.fromkeys([*agent.sensors, "gps"])),
    )
    agent.configure(env_config_to_dict(config))  # the camera and steps it acts with
    env = MultiONEnv(config, episodes=[episode])
    try:
        observation, _ = env.reset(options={"episode_id": episode_id})
        agent.reset()
        actions: list[int] = []
        done = False
        while not done:
            action = agent.act({k: v for k, v in observation.items() if k in agent.sensors})
            actions.append(action)
            observation, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
    finally:
        env.close()
    layers = agent.map  # type: ignore[attr-defined]
    return {
        "episode": episode_id,
        "image": image,
        "max_steps": max_steps,
        "actions": "".join(str(a) for a in actions),
        "obstacle_sha256": hashlib.sha256(np.packbits(layers.obstacle).tobytes()).hexdigest(),
        "free_sha256": hashlib.sha256(np.packbits(layers.free).tobytes()).hexdigest(),
    }


def _recorded() -> dict[tuple[str, int], dict[str, object]]:
    entries = json.loads(DATA.read_text())["episodes"]
    return {(e["episode"], e["image"]): e for e in entries}


@pytest.mark.parametrize(("episode_id", "image", "max_steps"), CASES)
def test_explorer_repeats_its_recorded_actions(episode_id: str, image: int, max_steps: int) -> None:
    expected = _recorded()[(episode_id, image)]
    assert expected["max_steps"] == max_steps
    got = play(episode_id, image, max_steps)
    want_actions, got_actions = str(expected["actions"]), str(got["actions"])
    first = next(
        (i for i, (a, b) in enumerate(zip(want_actions, got_actions, strict=False)) if a != b),
        min(len(want_actions), len(got_actions)),
    )
    assert got_actions == want_actions, f"first different action at step {first}"
    assert got["obstacle_sha256"] == expected["obstacle_sha256"]
    assert got["free_sha256"] == expected["free_sha256"]


def test_explorer_reads_the_depth_range_of_its_environment() -> None:
    # the actions were recorded with the sensor's range of the time, [0.5, 5] m; the default is
    # now [0, 10] m (the reference's). The explorer maps from 0.5-5 m either way, and decodes
    # depth with the range its environment reports: the same decisions in both
    episode_id, image, max_steps = CASES[3]
    got = play(episode_id, image, max_steps, depth=(0.5, 5.0))
    assert got["actions"] == _recorded()[(episode_id, image)]["actions"]


if __name__ == "__main__":
    records = []
    for case in CASES:
        tick = time.perf_counter()
        records.append(play(*case))
        print(case, len(str(records[-1]["actions"])), f"{time.perf_counter() - tick:.1f} s")
    DATA.write_text(json.dumps({"episodes": records}, indent=1) + "\n")
