"""`multion dataset import-multion`: original MultiON episode files onto the user's scans.

The test writes a MultiNav-v1 file the way the released ones are (habitat's y-up frame,
quaternions not at unit length, ``cylinder_<colour>`` in the reference's names) over a procedural
house exported as a y-up GLB, imports it, and compares with the episodes it came from.
"""

from __future__ import annotations

import gzip
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from multion.config.datasets import DatasetError, load_dataset, packaged_dataset_path
from multion.config.task import EnvConfig, TaskConfig
from multion.scenes.obj_export import export_obj
from multion.scenes.registry import layout_for
from multion.task.env import MultiONEnv
from multion.task.multion_import import (
    Y_UP_TO_Z_UP,
    category_of,
    habitat_to_world,
    import_multion,
    rotation_from_yaw,
    world_to_habitat,
    yaw_from_rotation,
)
from multion_client.constants import GOAL_CATEGORIES, REFERENCE_CATEGORY_NAMES

SCENE = "house-00061"


def reference_name(category: int) -> str:
    """The reference's name of one of our categories, written independently of the module."""
    ours = GOAL_CATEGORIES[category]
    return "cylinder_" + ("pink" if ours == "magenta" else ours)


@pytest.fixture(scope="module")
def originals():
    episodes = [e for e in load_dataset(packaged_dataset_path(2, "val")) if e.scene_id == SCENE]
    assert len(episodes) >= 3
    return episodes[:3]


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    """``<dir>/mp3d/<scan>/<scan>.glb``: the house turned y-up, as habitat's scans are."""
    root = tmp_path_factory.mktemp("scans")
    obj = export_obj(layout_for(SCENE), root / "house.obj")
    mesh = trimesh.load(obj, force="mesh")
    mesh.apply_transform(np.linalg.inv(Y_UP_TO_Z_UP))
    glb = root / "mp3d" / "scan61" / "scan61.glb"
    glb.parent.mkdir(parents=True)
    mesh.export(glb)
    assert mesh.bounds[1][1] > 2.0  # the walls' height is along y now
    return root


@pytest.fixture(scope="module")
def imported(tmp_path_factory, originals, scans):
    """The three episodes written as a MultiNav-v1 file and imported (once: a scan's grid takes
    a while to build)."""
    root = tmp_path_factory.mktemp("imported")
    source = multinav_file(root / "val.json.gz", originals)
    return import_multion(source, scans, root / "out" / "val.json.gz")


def multinav_file(path, episodes, scale=1.7):
    items = []
    for e in episodes:
        items.append(
            {
                "episode_id": e.episode_id,
                "scene_id": "mp3d/scan61/scan61.glb",
                "start_position": list(world_to_habitat(e.start_position)),
                "start_rotation": rotation_from_yaw(e.start_yaw, scale),
                "info": {"geodesic_distance": sum(e.geodesic_distances)},
                "goals": [
                    {
                        "object_category": reference_name(g.category),
                        "position": list(world_to_habitat(g.position)),
                    }
                    for g in e.goals
                ],
                "object_category": [reference_name(g.category) for g in e.goals],
            }
        )
    with gzip.open(path, "wt") as handle:
        json.dump({"episodes": items}, handle)
    return path


def test_frames_and_categories():
    assert habitat_to_world((1.0, 2.0, 3.0)) == (1.0, -3.0, 2.0)
    for yaw in np.linspace(-3.1, 3.1, 13):
        assert yaw_from_rotation(rotation_from_yaw(yaw, 2.5)) == pytest.approx(yaw, abs=1e-9)
    # identity: habitat's agent looks along -z, which is +y here
    assert yaw_from_rotation([0, 0, 0, 1]) == pytest.approx(math.pi / 2)
    assert [GOAL_CATEGORIES[category_of(f"cylinder_{n}")] for n in REFERENCE_CATEGORY_NAMES] == [
        "red",
        "green",
        "blue",
        "yellow",
        "white",
        "magenta",
        "black",
        "cyan",
    ]
    with pytest.raises(ValueError, match="cylinder_red"):
        category_of("guitar")
    with pytest.raises(ValueError, match="start_rotation"):
        yaw_from_rotation([0, 0, 0, 0])


def test_import_agrees_with_the_original_episodes(originals, imported):
    result = imported
    assert not result.skipped
    imported = load_dataset(result.path, num_goals=2)
    assert [e.episode_id for e in imported] == [e.episode_id for e in originals]
    for new, old in zip(imported, originals, strict=True):
        assert new.start_position == pytest.approx(old.start_position, abs=1e-4)
        assert math.remainder(new.start_yaw - old.start_yaw, 2 * math.pi) == pytest.approx(
            0, abs=1e-5
        )
        assert [g.category for g in new.goals] == [g.category for g in old.goals]
        for a, b in zip(new.goals, old.goals, strict=True):
            assert a.position == pytest.approx(b.position, abs=1e-4)
        # measured again on the scan's own grid: the same distances, to a cell or so
        assert new.geodesic_distances == pytest.approx(old.geodesic_distances, abs=0.15)
        assert new.scene_id.endswith("scan61.obj")
    assert max(abs(e) for e in result.geodesic_errors) < 0.3


def test_imported_dataset_plays_on_the_scan(originals, imported):
    result = imported
    config = EnvConfig(
        task=TaskConfig(num_goals=2),
        sensors=("rgb", "goal", "gps", "compass"),
        dataset=str(result.path),
    )
    env = MultiONEnv(config)
    try:
        obs, info = env.reset(seed=0, options={"episode_index": 0})
        assert info["episode_id"] == originals[0].episode_id
        # the agent stands where the original episode starts, facing the same way
        assert env.sim.position[:2] == pytest.approx(originals[0].start_position[:2], abs=1e-4)
        assert obs["goal"] == originals[0].goals[0].category
        # the house stands upright: something is seen ahead (not a sideways world)
        assert obs["rgb"].std() > 5
        env.step(1)
    finally:
        env.close()


def test_bad_files_are_refused_with_the_reason(tmp_path, originals, scans):
    broken = tmp_path / "broken.json.gz"
    broken.write_bytes(b"\x1f\x8bnot gzip")
    with pytest.raises(DatasetError, match="not a readable"):
        import_multion(broken, scans, tmp_path / "o.json.gz")
    source = multinav_file(tmp_path / "ok.json.gz", originals[:1])
    with pytest.raises(DatasetError, match="not found"):
        import_multion(source, tmp_path, tmp_path / "o.json.gz")
    data = json.loads(gzip.decompress(source.read_bytes()))
    data["episodes"][0]["goals"][0]["object_category"] = "guitar"
    (tmp_path / "real.json").write_text(json.dumps(data))
    with pytest.raises(DatasetError, match="guitar"):
        import_multion(tmp_path / "real.json", scans, tmp_path / "o.json.gz")
    assert not (tmp_path / "o.json.gz").exists()  # nothing half-written


def test_command_line(tmp_path, originals, scans, imported):
    source = multinav_file(tmp_path / "val.json.gz", originals[:2])
    out = imported.path.parent / "two.json.gz"  # beside the fixture's: its scan is converted
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "multion_agents.cli",
            "dataset",
            "import-multion",
            str(source),
            "--scenes",
            str(scans),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert "2 episodes" in done.stdout and "multion eval --dataset" in done.stdout
    assert len(load_dataset(out)) == 2
    missing = subprocess.run(
        [
            sys.executable,
            "-m",
            "multion_agents.cli",
            "dataset",
            "import-multion",
            str(source),
            "--scenes",
            str(tmp_path / "nowhere"),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert missing.returncode == 2 and "--scenes" in missing.stderr
