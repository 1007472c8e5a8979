"""Issue 53 item 2: the habitat ``Config`` of ``get_config`` holds every key of the reference's
default config tree (an agent of the MultiON 2022 starter reads ``TASK.OBJECTS_TYPE``), with the
served track's values where the track decides them and the reference's defaults elsewhere.

The reference trees are kept as this project's fixture, ``tests/data/habitat_reference_keys.json``
(``scripts/habitat_reference_keys.py`` writes it from the fetched repositories): every key path
of each tree and its default value.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from multion.leaderboard.challenge_file import load_challenge
from multion_client.habitat_config import Config, track_config

ROOT = Path(__file__).resolve().parents[2]
FIXTURE = json.loads((ROOT / "tests" / "data" / "habitat_reference_keys.json").read_text())
TREES: dict[str, dict[str, Any]] = FIXTURE["trees"]
PRECEDENCE = ("chal_2022", "main_old", "saimwani")
EXAMPLE = ROOT / "server" / "multion" / "leaderboard" / "examples" / "multion-2.0.toml"
SERVED = load_challenge(EXAMPLE, {"MULTION_CHALLENGE_SECRET": "x" * 32}).describe()["tracks"]


def walk(config: Config, path: str) -> Any:
    """``config.A.B.C`` for ``"A.B.C"``, by attribute as a participant's agent reads it."""
    node: Any = config
    for part in path.split("."):
        node = getattr(node, part)
    return node


def track_decided(track: dict[str, Any], phase: str) -> dict[str, Any]:
    """What the served track says of the reference's keys, written out by hand."""
    camera = {"width": 256, "height": 256, "hfov_deg": 79.0, "sensor_height": 0.88}
    camera.update(track.get("camera", {}))
    success = track.get("success_distance", 1.5)
    objects = {"colours": "CYL", "objects": "REAL"}[track.get("goal_set", "colours")]
    decided = {
        "ENVIRONMENT.MAX_EPISODE_STEPS": track["max_steps"],
        "TASK.TOP_DOWN_MAP.MAX_EPISODE_STEPS": track["max_steps"],
        "SIMULATOR.TURN_ANGLE": 30.0,
        "SIMULATOR.FORWARD_STEP_SIZE": 0.25,
        "SIMULATOR.AGENT_0.HEIGHT": camera["sensor_height"],
        "SIMULATOR.AGENT_0.RADIUS": 0.1,
        "SIMULATOR.AGENT_0.SENSORS": [
            f"{s.upper()}_SENSOR" for s in ("rgb", "depth") if s in track["sensors"]
        ],
        "TASK.SENSORS": [
            habitat
            for s, habitat in (
                ("goal", "MULTI_OBJECT_GOAL_SENSOR"),
                ("compass", "COMPASS_SENSOR"),
                ("gps", "GPS_SENSOR"),
            )
            if s in track["sensors"]
        ],
        "TASK.TYPE": "MultiObjectNav-v1",
        "TASK.POSSIBLE_ACTIONS": ["FOUND", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT"],
        "TASK.SUCCESS_DISTANCE": success,
        "TASK.SUCCESS.SUCCESS_DISTANCE": success,
        "TASK.SUB_SUCCESS.SUCCESS_DISTANCE": success,
        "TASK.PERCENTAGE_SUCCESS.SUCCESS_DISTANCE": success,
        "TASK.ORACLE_SUB_SUCCESS.SUCCESS_DISTANCE": success,
        "TASK.PROGRESS.SUCCESS_DISTANCE": success,
        "TASK.OBJECTS_TYPE": objects,
        "TASK.NUM_GOALS": track["num_goals"],
        "DATASET.NUM_GOALS": track["num_goals"],
        "TASK.NUM_DISTRACTORS": track.get("num_distractors", 0),
        "TASK.INCLUDE_DISTRACTORS": track.get("num_distractors", 0) > 0,
        "DATASET.SPLIT": phase,
    }
    for sensor in ("RGB_SENSOR", "DEPTH_SENSOR", "SEMANTIC_SENSOR"):
        decided[f"SIMULATOR.{sensor}.WIDTH"] = camera["width"]
        decided[f"SIMULATOR.{sensor}.HEIGHT"] = camera["height"]
        decided[f"SIMULATOR.{sensor}.HFOV"] = camera["hfov_deg"]
        decided[f"SIMULATOR.{sensor}.POSITION"] = [0.0, camera["sensor_height"], 0.0]
    return decided


def test_the_fixture_holds_the_reference_trees() -> None:
    assert set(TREES) == set(PRECEDENCE)
    assert TREES["chal_2022"]["TASK.OBJECTS_TYPE"] == "CYL"  # default.py l. 239
    assert len(set().union(*TREES.values())) == 386


@pytest.mark.parametrize("track", SERVED, ids=[t["name"] for t in SERVED])
def test_every_reference_key_is_there_with_the_tracks_value_or_the_reference_default(
    track: dict[str, Any],
) -> None:
    config = track_config(track, "minival")
    config.freeze()
    decided = track_decided(track, "minival")
    for tree in PRECEDENCE:
        for path in TREES[tree]:
            walk(config, path)  # AttributeError: the config has no key ...
    for path in set().union(*TREES.values()):
        default = next(TREES[tree][path] for tree in PRECEDENCE if path in TREES[tree])
        expected = decided.get(path, default)
        assert walk(config, path) == expected, path
    assert config.TASK.ACTIONS.FOUND.TYPE == "FoundObjectAction"
    assert config.SIMULATOR.HEAD_RGB_SENSOR.WIDTH == 640  # a camera the track does not size


def test_the_real_objects_track_reads_real() -> None:
    by_name = {t["name"]: t for t in SERVED}
    cylinders = track_config(by_name["5-on-cylinders"])
    objects = track_config(by_name["5-on-objects"])
    assert (cylinders.TASK.OBJECTS_TYPE, objects.TASK.OBJECTS_TYPE) == ("CYL", "REAL")
    assert objects.TASK.REAL_OBJECTS_PATH == "data/multion_real_objects"
    assert cylinders.TASK.INCLUDE_DISTRACTORS is True and cylinders.TASK.NUM_DISTRACTORS == 3
    shapes = track_config({**by_name["5-on-cylinders"], "goal_set": "shapes"})
    assert shapes.TASK.OBJECTS_TYPE == "SHAPES"  # neither of the reference's types


def test_the_keys_merge_and_stay_frozen() -> None:
    config = track_config(SERVED[0], "minival")
    config.freeze()
    clone = config.clone()
    assert clone == config and clone.SIMULATOR.HABITAT_SIM_V0.is_frozen()
    clone.defrost()
    clone.merge_from_list(
        ["TASK.OBJECTS_TYPE", "REAL", "SIMULATOR.HABITAT_SIM_V0.GPU_DEVICE_ID", 1]
    )
    assert (clone.TASK.OBJECTS_TYPE, clone.SIMULATOR.HABITAT_SIM_V0.GPU_DEVICE_ID) == ("REAL", 1)
    assert config.TASK.OBJECTS_TYPE == "CYL"
