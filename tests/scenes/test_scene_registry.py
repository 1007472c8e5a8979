"""Scene ids, splits and id → layout."""

from __future__ import annotations

import re

import pytest

from multion.config.scenes import SPLIT_SIZES
from multion.scenes.registry import is_mesh_scene, layout_for, scene_ids, scene_split


def test_splits_have_matterport_counts_and_are_disjoint():
    ids = {split: scene_ids(split) for split in ("train", "val", "test")}
    assert {k: len(v) for k, v in ids.items()} == {"train": 61, "val": 11, "test": 18}
    assert SPLIT_SIZES == {"train": 61, "val": 11, "test": 18}
    everything = ids["train"] + ids["val"] + ids["test"]
    assert len(set(everything)) == 90
    assert sorted(everything) == [f"house-{n:05d}" for n in range(90)]
    assert ids["train"][0] == "house-00000" and ids["val"][0] == "house-00061"
    assert ids["test"][-1] == "house-00089"
    for split, members in ids.items():
        assert all(scene_split(s) == split for s in members)


def test_scene_split_of_other_ids_is_none():
    assert scene_split("house-00090") is None
    assert scene_split("room-6x4") is None
    assert scene_split("/data/scan.glb") is None
    assert scene_split("house-42") == "train"  # same house as house-00042


def test_unknown_split_names_the_valid_ones():
    with pytest.raises(ValueError, match="train, val, test"):
        scene_ids("validation")


def test_layout_for_houses_and_rooms():
    house = layout_for("house-00042")
    assert house.scene_id == "house-00042"
    assert 8 <= len(house.rooms) <= 16
    assert layout_for("house-00042") is house  # cached
    assert layout_for("house-123456").metadata["seed"] == "123456"  # beyond the splits works too
    assert layout_for("room-6x4").rooms[0].rect == (0.0, 0.0, 6.0, 4.0)
    assert layout_for("room-10x2.5").rooms[0].rect == (0.0, 0.0, 10.0, 2.5)


@pytest.mark.parametrize(
    "bad", ["house-", "house-abc", "House-00001", "room-6", "room-6x", "room-x4", "kitchen", ""]
)
def test_bad_ids_raise_a_clear_error(bad):
    with pytest.raises(ValueError) as info:
        layout_for(bad)
    message = str(info.value)
    assert repr(bad) in message and "house-NNNNN" in message and "room-WxD" in message


def test_zero_sized_and_huge_rooms_are_rejected():
    for scene in ("room-0x4", "room-4x50.5", "room-100000x100000"):
        with pytest.raises(ValueError, match=r"must be in \(0, 50\] metres"):
            layout_for(scene)
    assert layout_for("room-50x2").scene_id == "room-50x2"


def test_mesh_scenes_are_recognised_but_not_built_here():
    for path in ["/data/mp3d/17DRP5sb8fy.glb", "scan.OBJ", "a/b.gltf", "c.ply"]:
        assert is_mesh_scene(path)
    for sid in ["house-00001", "room-6x4", "scan.obj.gz", "glb"]:
        assert not is_mesh_scene(sid)
    with pytest.raises(ValueError, match="mesh"):
        layout_for("scan.glb")


def test_a_house_is_a_pure_function_of_its_number_and_the_parameters():
    from multion.scenes.house import generate_house
    from multion.scenes.registry import GENERATOR_VERSION, HOUSE_CONFIG, house_parameters

    assert house_parameters("house-00042") == (42, HOUSE_CONFIG)
    assert generate_house(42, HOUSE_CONFIG, scene_id="house-00042") == layout_for("house-00042")
    assert isinstance(GENERATOR_VERSION, int) and GENERATOR_VERSION >= 2
    with pytest.raises(ValueError, match="house-NNNNN"):
        house_parameters("room-6x4")


def test_scene_ids_are_checked_without_building_and_refused_with_a_typed_error():
    from multion.scenes.registry import SceneIdError, check_scene_id

    for good in ("house-00042", "house-1000000000123-r3", "room-6x4", "scans/a.glb"):
        check_scene_id(good)
    for bad, allowed in [
        ("hidden-minival-3-on-00000", "house-NNNNN-rK"),
        ("house-" + "9" * 19, "at most 18 digits"),
        ("house-7-r0", "1..16"),
        ("room-0x4", "(0, 50] metres"),
    ]:
        with pytest.raises(SceneIdError, match=re.escape(allowed)):
            check_scene_id(bad)
        with pytest.raises(SceneIdError):  # what the env turns into a 4xx, by its type
            layout_for(bad)
