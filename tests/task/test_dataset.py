"""Datasets: generated episodes meet every constraint, are reproducible, and bad files are refused."""

import gzip
import json

import numpy as np
import pytest

from multion.config.datasets import DatasetError, load_dataset, parse_task, save_dataset
from multion.scenes.registry import GENERATOR_VERSION
from multion.sim.geodesic import distance_field
from multion.sim.simulator import Simulator
from multion.task.generate import generate_episodes

SCENES = ["house-00061", "house-00062"]


@pytest.fixture(scope="module")
def episodes():
    return generate_episodes(3, "val", 12, seed=7, scenes=SCENES, progress=False)


def test_generated_episodes_meet_the_constraints(episodes):
    sim = Simulator()
    assert len(episodes) == 12 and {e.scene_id for e in episodes} == set(SCENES)
    assert len({e.episode_id for e in episodes}) == 12
    for episode in episodes:
        grid = sim.load_scene(episode.scene_id)
        categories = [g.category for g in episode.goals]
        assert len(set(categories)) == 3 and all(0 <= c < 8 for c in categories)
        points = [np.array(episode.start_position[:2])] + [
            np.array(g.position[:2]) for g in episode.goals
        ]
        assert grid.is_navigable(np.array(points)).all()  # same floor, on the navigable grid
        for previous, goal in zip(points[:-1], points[1:], strict=True):
            d = float(grid.lookup(distance_field(grid, goal, 0.05), previous, outside=np.inf))
            assert 2.0 <= d <= 20.0  # reachable, neither trivial nor too far
        goals = points[1:]
        for i in range(3):
            for j in range(i + 1, 3):
                assert np.hypot(*(goals[i] - goals[j])) >= 1.0
        assert all(2.0 <= d <= 20.0 for d in episode.geodesic_distances)


def test_generation_is_reproducible(episodes, tmp_path):
    again = generate_episodes(3, "val", 12, seed=7, scenes=SCENES, progress=False)
    assert again == episodes
    a = save_dataset(tmp_path / "a.json.gz", episodes, 3, "val")
    b = save_dataset(tmp_path / "b.json.gz", again, 3, "val")
    assert a.read_bytes() == b.read_bytes()
    other = generate_episodes(3, "val", 12, seed=8, scenes=SCENES, progress=False)
    assert other != episodes


def test_round_trip(episodes, tmp_path):
    path = save_dataset(tmp_path / "d.json.gz", episodes, 3, "val")
    loaded = load_dataset(path)
    assert [e.to_dict() for e in loaded] == [e.to_dict() for e in episodes]


def write(path, payload, raw=False):
    with gzip.open(path, "wb") as handle:
        handle.write(payload if raw else json.dumps(payload).encode())
    return path


def good_payload(episodes):
    return {
        "format": "multion-episodes",
        "version": 3,
        "scene_generator_version": GENERATOR_VERSION,
        "num_goals": 3,
        "split": "val",
        "episodes": [e.to_dict() for e in episodes[:3]],
    }


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda p: p.update(format="other"), "not a MultiON dataset"),
        (lambda p: p.update(version=99), "version 99"),
        (lambda p: p.update(version=1), "made for the old houses"),
        (
            lambda p: p.update(scene_generator_version=GENERATOR_VERSION - 1),
            f"scene generator version {GENERATOR_VERSION - 1}",
        ),
        (lambda p: p.pop("scene_generator_version"), "scene generator version None"),
        (lambda p: p.update(episodes=[]), "non-empty list"),
        (
            lambda p: p["episodes"][1].pop("goals"),
            "episode 1: malformed (missing field 'episode.goals')",
        ),
        (lambda p: p["episodes"][0]["goals"][0].update(category=9), "category 9 is not in 0..7"),
        (
            lambda p: p["episodes"][0]["goals"][1].update(
                category=p["episodes"][0]["goals"][0]["category"]
            ),
            "repeat",
        ),
        (
            lambda p: p["episodes"][2].update(episode_id=p["episodes"][0]["episode_id"]),
            "duplicate episode_id",
        ),
        (
            lambda p: p["episodes"][0].update(start_position=[1, 2]),
            "start_position must be a list of 3",
        ),
        (lambda p: p["episodes"][0]["goals"].pop(), "has 2 goals, the dataset is for 3"),
    ],
)
def test_inconsistent_files_are_refused_with_file_and_problem(episodes, tmp_path, mutate, message):
    payload = good_payload(episodes)
    mutate(payload)
    path = write(tmp_path / "bad.json.gz", payload)
    with pytest.raises(DatasetError) as error:
        load_dataset(path)
    assert str(path) in str(error.value) and message in str(error.value)


def test_corrupt_files_are_refused(tmp_path):
    not_gzip = tmp_path / "plain.json.gz"
    not_gzip.write_text("{}")
    truncated = write(tmp_path / "cut.json.gz", b'{"format": "multion-ep', raw=True)
    for path in (not_gzip, truncated, tmp_path / "missing.json.gz"):
        with pytest.raises(DatasetError, match=str(path.name)):
            load_dataset(path)


def test_parse_task():
    assert parse_task("3-on") == parse_task("3-ON") == parse_task("3on") == parse_task(3) == 3
    with pytest.raises(ValueError, match="unknown task"):
        parse_task("9-on")


def test_files_record_their_versions_and_rooms_need_no_generator_version(episodes, tmp_path):
    from multion.config.datasets import VERSION, read_header
    from multion.config.episode import Episode, Goal

    header = read_header(save_dataset(tmp_path / "d.json.gz", episodes, 3, "val"))
    assert header["version"] == VERSION == 3
    assert header["scene_generator_version"] == GENERATOR_VERSION
    assert header["num_distractors"] == 0
    # empty rooms do not change with the house generator: such a file stays usable
    room = Episode("r", "room-6x4", (1.0, 1.0, 0.0), 0.0, (Goal(0, (4.0, 2.0, 0.0)),))
    path = write(tmp_path / "room.json.gz", {
        "format": "multion-episodes", "version": 3, "scene_generator_version": 1,
        "num_goals": 1, "split": "val", "episodes": [room.to_dict()],
    })  # fmt: skip
    assert load_dataset(path)[0].scene_id == "room-6x4"


def test_version_2_files_are_refused_with_the_reason(episodes, tmp_path):
    # version 2 files were sampled without the step-path check: some of their goals cannot be
    # reached by the agent's steps, so they must be regenerated, not silently played
    path = write(tmp_path / "v2.json.gz", {**good_payload(episodes), "version": 2})
    with pytest.raises(DatasetError, match="version 2 files may hold episodes whose goals"):
        load_dataset(path)
