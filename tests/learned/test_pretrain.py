"""Pretraining on oracle-map crops (``learned/pretrain.py``, ``multion train --pretrain-map``)."""

from __future__ import annotations

import csv
import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from multion.config.codec import env_config_from_dict
from multion.config.task import EnvConfig
from multion_agents.learned.checkpoint import load_checkpoint
from multion_agents.learned.models import build_policy, model_spec
from multion_agents.learned.ppo import Args
from multion_agents.learned.pretrain import (
    MapPretraining,
    accuracy,
    blank_frames,
    pose_label,
    pretrain_map,
    sample_map_crops,
)
from multion_agents.learned.rollout_envs import training_env_config
from multion_agents.learned.training_run import train
from multion_client.constants import Action

EGO_SIZE = 25


def _config(dataset: Path | None = None) -> EnvConfig:
    spec = model_spec("oracle-map")
    config = training_env_config(1, spec.train_sensors, 36, "train", None, 40, dataset)
    config["maps"] = {"ego_size": EGO_SIZE}
    return env_config_from_dict(config)


@pytest.mark.parametrize(
    ("goal", "geodesic", "action"),
    [
        ((3.0, 0.0), 3.0, Action.MOVE_FORWARD),
        ((3.0, 3.0 * math.tan(math.radians(14))), 3.1, Action.MOVE_FORWARD),
        ((3.0, 3.0 * math.tan(math.radians(16))), 3.1, Action.TURN_LEFT),
        ((0.0, 2.0), 2.0, Action.TURN_LEFT),
        ((0.0, -2.0), 2.0, Action.TURN_RIGHT),
        ((-3.0, -0.1), 3.0, Action.TURN_RIGHT),
        ((1.0, 0.5), 1.1, Action.FOUND),
        ((1.0, 0.5), 1.3, Action.TURN_LEFT),  # out of reach along the floor: the turn
    ],
)
def test_pose_labels_by_hand(goal, geodesic, action) -> None:
    label = pose_label(np.zeros(2), 0.0, np.asarray(goal), geodesic, 1.2, 30.0)
    assert label == action


def test_pose_labels_turn_with_the_agent() -> None:
    # facing +y, a goal at +x is to the right
    assert pose_label(np.zeros(2), math.pi / 2, np.array([2.0, 0.0]), 2.0, 1.2, 30.0) == (
        Action.TURN_RIGHT
    )


def _goal_cell(crop: np.ndarray, category: int) -> tuple[float, float] | None:
    """The goal's (forward, left) offset in cells from the agent's cell: the middle of its
    square of cells (3 × 3 by default, ``maps.goal_cells``)."""
    rows, cols = np.nonzero(crop[..., 1] == category + 1)
    if not 1 <= len(rows) <= 9:
        return None
    half = crop.shape[0] // 2
    return half - float(rows.mean()), half - float(cols.mean())


def test_crops_show_the_goal_where_the_labels_say() -> None:
    # three houses: about a third of the crops have a goal far enough and off the edges to check
    settings = MapPretraining(max_distance=5.0, poses_per_scene=150)
    crops = sample_map_crops(_config(), 450, 3, settings)
    assert crops.maps.shape == (450, EGO_SIZE, EGO_SIZE, 2)
    assert set(np.unique(crops.labels)) == {int(a) for a in Action}
    checked = agreed = 0
    for crop, category, label in zip(crops.maps, crops.goals, crops.labels, strict=True):
        cell = _goal_cell(crop, int(category))
        assert cell is not None, "a goal within 5 m is always inside a 25-cell crop"
        if label == Action.FOUND or max(abs(cell[0]), abs(cell[1])) < 4:
            continue  # a goal cell next to the agent gives its bearing only roughly
        bearing = math.atan2(cell[1], cell[0])
        edge = abs(abs(bearing) - math.radians(15))
        if edge < math.radians(8) or abs(bearing) > math.radians(172):
            continue  # one map cell off could flip the side
        wanted = (
            Action.MOVE_FORWARD
            if abs(bearing) < math.radians(15)
            else (Action.TURN_LEFT if bearing > 0 else Action.TURN_RIGHT)
        )
        checked += 1
        agreed += int(label == wanted)
    assert checked > 100
    assert agreed == checked


def test_hidden_goal_objects_stay_on_the_map(room_dataset: Path) -> None:
    # oracle-map-hidden-objects renders no goal cylinders, but its map still shows the goals
    config = _config(room_dataset)
    config = replace(config, task=replace(config.task, goals_visible=False))
    crops = sample_map_crops(config, 20, 0, MapPretraining(poses_per_scene=20))
    pairs = zip(crops.maps, crops.goals, strict=True)
    assert all((crop[..., 1] == goal + 1).any() for crop, goal in pairs)


def test_the_same_seed_draws_the_same_crops(room_dataset: Path) -> None:
    settings = MapPretraining(poses_per_scene=20)
    first = sample_map_crops(_config(room_dataset), 50, 7, settings)
    second = sample_map_crops(_config(room_dataset), 50, 7, settings)
    other = sample_map_crops(_config(room_dataset), 50, 8, settings)
    assert np.array_equal(first.maps, second.maps)
    assert np.array_equal(first.labels, second.labels)
    assert not np.array_equal(first.maps, other.maps)


def test_pretraining_learns_where_the_goal_is(tmp_path: Path, room_dataset: Path) -> None:
    # in the empty room (fast to load), held out at other poses of other episodes
    torch.manual_seed(0)
    config = _config(room_dataset)
    policy = build_policy("oracle-map", config)
    settings = MapPretraining(
        steps=400, samples=600, held_out=200, poses_per_scene=20, held_out_split="train"
    )
    result = pretrain_map(policy, config, settings, tmp_path, progress=False)
    rows = list(csv.DictReader((tmp_path / "pretrain.csv").open()))
    assert [int(r["step"]) for r in rows] == [0, 100, 200, 300, 400]
    assert float(rows[0]["held_out_accuracy"]) == pytest.approx(result["held_out_accuracy_before"])
    held_out = sample_map_crops(config, 200, settings.seed + 1, settings, "train")
    majority = np.bincount(held_out.labels).max() / len(held_out)
    assert result["held_out_accuracy"] >= majority + 0.2, "more than the labels' frequencies"
    blank = blank_frames(policy, config)
    assert accuracy(policy, blank, held_out) == pytest.approx(result["held_out_accuracy"])


def test_train_pretrains_once_and_resume_keeps_it(tmp_path: Path, room_dataset: Path) -> None:
    out = tmp_path / "run"
    args = Args(
        agent="oracle-map", task="1-on", frames=64, envs=2, rollout_steps=32, image_size=36,
        dataset=str(room_dataset), max_steps=40, out=str(out), progress=False,
        tensorboard=False, env_overrides={"maps": {"ego_size": 25}},
        pretrain_map=MapPretraining(steps=20, samples=200, held_out=100, poses_per_scene=100),
    )  # fmt: skip
    train(args)
    rows = list(csv.DictReader((out / "pretrain.csv").open()))
    assert [int(r["step"]) for r in rows] == [0, 20]
    pretrained = load_checkpoint(out / "checkpoint.pt")
    assert pretrained["args"]["pretrain_map"]["steps"] == 20
    plain = tmp_path / "plain"
    train(Args(**{**args.__dict__, "out": str(plain), "pretrain_map": MapPretraining()}))
    assert not (plain / "pretrain.csv").exists()
    different = [
        name
        for name, weights in pretrained["model"].items()
        if not torch.equal(weights, load_checkpoint(plain / "checkpoint.pt")["model"][name])
    ]
    assert "actor.weight" in different and any(n.startswith("memory.") for n in different)
    train(Args(**{**args.__dict__, "frames": 128, "resume": True}))
    assert len(list(csv.DictReader((out / "pretrain.csv").open()))) == 2
    assert load_checkpoint(out / "checkpoint.pt")["frames"] == 128


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--agent", "no-map", "--pretrain-map", "10"], "which no-map does not read"),
        (["--pretrain-map", "20001"], "pretrain_map.steps = 20001 is out of range"),
        (["--pretrain-map", "-1"], "pretrain_map.steps = -1 is out of range"),
    ],
)
def test_train_cli_rejects_bad_pretraining(tmp_path: Path, capsys, flags, message) -> None:
    from multion_agents.cli import main

    code = main(["train", *flags, "--frames", "64", "--out", str(tmp_path)])
    assert code == 2
    assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "checkpoint.pt").exists()
