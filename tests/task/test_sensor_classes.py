"""One class per sensor (issue 45): the registry is read by the config, the env, the spaces, the
memory estimate and the challenge, and the env observes exactly what it did before the classes.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np
import pytest
from gymnasium import spaces

from multion.config.episode import Episode, Goal
from multion.config.sensors import SENSOR_SPECS, SENSORS, sensor_spec, sensors_with_access
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, MapConfig, TaskConfig
from multion.leaderboard.challenge import (
    ORACLE_SENSORS,
    STANDARD_SENSORS,
    ChallengeError,
    Phase,
    Track,
)
from multion.task.env import MultiONEnv
from multion.task.memory import estimate_env_bytes
from multion.task.sensors import BYTES_PER_MAP_CELL, OBSERVATION_ORDER, SENSOR_CLASSES
from multion.task.spaces import build_observation_space

ACTIONS = (1, 1, 2, 1, 3, 3, 1, 1, 2, 1, 1, 0)
"""Forward, turns and a last (wrong) FOUND: every sensor changes along the way."""


def observation_digests(
    config: EnvConfig, seed: int, episodes: Sequence[Episode] | None = None
) -> dict[str, object]:
    """Per sensor, a digest of its dtype, shape and bytes over a seeded episode; and key order."""
    env = MultiONEnv(config, episodes=episodes)
    try:
        obs, _ = env.reset(seed=seed)
        frames = [obs]
        for action in ACTIONS:
            obs, *_ = env.step(action)
            frames.append(obs)
    finally:
        env.close()
    digests: dict[str, object] = {"order": list(frames[0])}
    for key in frames[0]:
        digest = hashlib.sha256()
        for frame in frames:
            value = np.asarray(frame[key])
            digest.update(f"{value.dtype}{value.shape}".encode())
            digest.update(value.tobytes())
        digests[key] = digest.hexdigest()[:16]
    return digests


OLD_ORDER = ["rgb", "depth", "goal_mask", "goal", "goal_onehot", "goal_distance", "gps", "compass",
             "oracle_map", "oracle_ego_map"]  # fmt: skip
ADDED_SINCE = ("goal_vector",)
SMALL = CameraConfig(width=32, height=24)
ROOM_EPISODE = Episode(
    "room", "room-6x4", (1.0, 2.0, 0.0), 0.0,
    (Goal(2, (4.0, 2.0, 0.0)), Goal(5, (2.0, 3.2, 0.0))),
    distractors=(Goal(6, (4.5, 1.0, 0.0)),),
)  # fmt: skip
# Recorded with the code before the sensor classes (commit 5f2344c's task/env.py _observe):
# a packaged 3-on episode, a 3-on-distractors one (sensors listed in reverse) and a room with
# a goal and a distractor in view (goal_mask non-zero), depth in metres.
BEFORE = {
    "3-on": {"order": OLD_ORDER, "rgb": "66c1361c2658a651", "depth": "6687c8313d2631c4",
             "goal_mask": "325ea103acb47e54", "goal": "f562468a392d74c6",
             "goal_onehot": "5a1820f32416ac72", "goal_distance": "24f3edc5930eb4ba",
             "gps": "89a5db98675e46b3", "compass": "062c1f5bfbce4338",
             "oracle_map": "6b6a440a866cc409", "oracle_ego_map": "0772549ddc5fa48c"},
    "3-on-distractors": {"order": OLD_ORDER, "rgb": "0ae431f420385211",
                         "depth": "5816cf20513f0f4a", "goal_mask": "325ea103acb47e54",
                         "goal": "d24c55ed4d59e0e0", "goal_onehot": "d0455c985779ded0",
                         "goal_distance": "6736c497ffc80771", "gps": "480232dfcd42f633",
                         "compass": "062c1f5bfbce4338", "oracle_map": "edb022efbb2b7aaa",
                         "oracle_ego_map": "ec951cacd4a620f0"},
    "room": {"order": OLD_ORDER, "rgb": "7d7b8bc4777bbaa6", "depth": "7eec2a7b1b5fdbb5",
             "goal_mask": "128731604c164bb0", "goal": "f91020f9e356e8a5",
             "goal_onehot": "a969d5007b73a18b", "goal_distance": "23ad7a7316614c4b",
             "gps": "92692448e6de5bcc", "compass": "062c1f5bfbce4338",
             "oracle_map": "98bc2396af8a33d2", "oracle_ego_map": "8e212eb7c2ebea82"},
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BEFORE))
def test_observations_are_bit_for_bit_those_before_the_sensor_classes(case: str) -> None:
    if case == "3-on":
        digests = observation_digests(EnvConfig(camera=SMALL, sensors=SENSORS), 4)
    elif case == "3-on-distractors":
        task = TaskConfig(num_goals=3, num_distractors=3)
        config = EnvConfig(task=task, camera=SMALL, sensors=tuple(reversed(SENSORS)))
        digests = observation_digests(config, 7)
    else:
        camera = CameraConfig(width=40, height=30, normalize_depth=False)
        task = TaskConfig(num_goals=2, num_distractors=1)
        config = EnvConfig(task=task, camera=camera, sensors=SENSORS)
        digests = observation_digests(config, 0, [ROOM_EPISODE])
    # sensors added since (issue 51's goal_vector) come last and change none of the others
    assert digests["order"][: len(OLD_ORDER)] == OLD_ORDER
    assert digests["order"][len(OLD_ORDER) :] == list(ADDED_SINCE)
    old = {key: value for key, value in digests.items() if key not in ADDED_SINCE}
    assert old == {**BEFORE[case], "order": digests["order"]}


def test_one_class_per_registered_sensor_in_registry_order() -> None:
    assert tuple(SENSOR_CLASSES) == SENSORS == tuple(spec.name for spec in SENSOR_SPECS)
    for name, sensor in SENSOR_CLASSES.items():
        assert sensor.spec is sensor_spec(name)
    assert sorted(OBSERVATION_ORDER) == sorted(SENSORS)
    with pytest.raises(KeyError, match="known sensors"):
        sensor_spec("lidar")


def test_each_space_is_its_class_space() -> None:
    config = EnvConfig(camera=CameraConfig(width=20, height=10, normalize_depth=False),
                       maps=MapConfig(ego_size=21), sensors=SENSORS)  # fmt: skip
    space = build_observation_space(config)
    assert list(space.spaces) == sorted(SENSORS)  # gymnasium sorts a Dict's keys
    assert space["depth"] == spaces.Box(0.0, config.camera.max_depth, (10, 20, 1), np.float32)
    assert space["oracle_ego_map"] == spaces.Box(0, 255, (21, 21, 2), np.uint8)
    assert space["goal_mask"] == spaces.Box(0, 8, (10, 20), np.uint8)


def test_privileged_sensors_decide_the_tracks() -> None:
    privileged = {spec.name for spec in SENSOR_SPECS if spec.privileged}
    assert privileged == {
        "oracle_map", "oracle_ego_map", "goal_distance", "goal_mask", "goal_vector"
    }  # fmt: skip
    assert STANDARD_SENSORS == ("rgb", "depth", "goal", "goal_onehot", "gps", "compass")
    assert ORACLE_SENSORS == (*STANDARD_SENSORS, "oracle_map", "oracle_ego_map", "goal_distance")
    assert sensors_with_access(("training",)) == ("goal_mask", "goal_vector")


@pytest.mark.parametrize(
    ("kind", "sensors", "refused"),
    [("standard", ("rgb", "goal_distance"), "goal_distance"),
     ("standard", ("goal", "oracle_map"), "oracle_map"),
     ("oracle", ("rgb", "goal_mask"), "goal_mask")],
)  # fmt: skip
def test_a_track_lists_no_sensor_beyond_its_kind(
    kind: str, sensors: tuple[str, ...], refused: str
) -> None:
    with pytest.raises(ChallengeError, match=rf"track 't': sensor\(s\) \['{refused}'\] .* {kind}"):
        Track("t", num_goals=1, kind=kind, sensors=sensors, phases=(Phase("p", episodes=1),))
    Track("t", num_goals=1, kind="oracle", sensors=("rgb", "oracle_map", "goal_distance"),
          phases=(Phase("p", episodes=1),))  # fmt: skip


def test_the_two_oracle_map_sensors_share_one_map_in_the_estimate() -> None:
    maps = MapConfig(ego_size=101)
    base = estimate_env_bytes(EnvConfig(maps=maps, sensors=("goal",)))
    one = estimate_env_bytes(EnvConfig(maps=maps, sensors=("goal", "oracle_map")))
    both = estimate_env_bytes(EnvConfig(maps=maps, sensors=("oracle_map", "oracle_ego_map")))
    assert one - base == both - base == 101**2 * BYTES_PER_MAP_CELL
