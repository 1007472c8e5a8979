"""``--found-head-label seen`` (issue 51): the FOUND head learns that FOUND would succeed where
the goal has been in view at some step of the episode so far, not only where the frame shows
it, so that an agent standing on a goal its camera no longer shows may call it. The labels on
hand-made steps, the sensors a run carries, and a checkpoint that resumes only with the label it
was trained with."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import pytest
import torch
from test_recipe_options import tiny_args

from multion.config.ranges import ConfigError
from multion_agents.learned.checkpoint import CheckpointError, load_checkpoint, load_policy
from multion_agents.learned.found_supervision import (
    FOUND_LABEL_SENSOR,
    IN_VIEW_SENSOR,
    found_label_sensors,
    found_targets,
    head_may_know,
)
from multion_agents.learned.goal_heads import GOAL_VECTOR
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_run import run_env_config, train


def _frames() -> dict[str, torch.Tensor]:
    """Two envs over three steps (T, B). Env 0 sees its goal (category 2) at step 0 from 1.2 m,
    then stands on it at 0.2 m and 0.0 m with the frame showing nothing; env 1 never sees its
    goal and passes within 1 m of it at step 2."""
    mask = torch.zeros(3, 2, 4, 4, dtype=torch.uint8)
    mask[0, 0, 2, 2] = 3
    seen = torch.tensor([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    vector = torch.stack([seen, torch.zeros(3, 2), torch.ones(3, 2)], dim=-1)
    return {
        IN_VIEW_SENSOR: mask,
        "goal": torch.tensor([[2, 1]] * 3),
        GOAL_VECTOR: vector,
        FOUND_LABEL_SENSOR: torch.tensor([[[1.2], [3.0]], [[0.2], [2.0]], [[0.0], [1.0]]]),
    }


def test_in_view_labels_only_the_step_that_shows_the_goal() -> None:
    frames = _frames()
    may_know = head_may_know(frames, "in-view")
    targets = found_targets(frames[FOUND_LABEL_SENSOR], 1.5, may_know)
    assert targets.labels.tolist() == [[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]]


def test_seen_labels_standing_on_a_goal_seen_earlier_but_not_one_never_seen() -> None:
    frames = _frames()
    may_know = head_may_know(frames, "seen")
    assert may_know.tolist() == [[True, False]] * 3
    targets = found_targets(frames[FOUND_LABEL_SENSOR], 1.5, may_know)
    assert targets.labels.tolist() == [[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]]
    assert targets.weights is None  # the head's loss, unweighted, as with in-view


def test_each_label_carries_only_the_sensor_it_reads(tmp_path: Path, room_dataset: Path) -> None:
    in_view = tiny_args(tmp_path, room_dataset, found_head=1.0)
    seen = tiny_args(tmp_path, room_dataset, found_head=1.0, found_head_label="seen")
    assert found_label_sensors(in_view) == (FOUND_LABEL_SENSOR, IN_VIEW_SENSOR)
    assert found_label_sensors(seen) == (FOUND_LABEL_SENSOR, GOAL_VECTOR)
    assert GOAL_VECTOR in run_env_config(seen).sensors
    assert GOAL_VECTOR not in run_env_config(in_view).sensors
    # no-map reads no goal_mask, and the seen label does not either: the env renders none
    assert IN_VIEW_SENSOR in run_env_config(in_view).sensors
    assert IN_VIEW_SENSOR not in run_env_config(seen).sensors
    # with the goal heads, which read goal_vector already, the env lists it once
    both = dataclasses.replace(seen, goal_heads=True)
    assert run_env_config(both).sensors.count(GOAL_VECTOR) == 1


def test_the_label_needs_a_found_head_and_one_of_two_values() -> None:
    assert Args().found_head_label == "in-view"  # off in the paper's recipe: no head at all
    with pytest.raises(ConfigError, match="--found-head-label .* needs --found-head"):
        Args(found_head_label="seen")
    with pytest.raises(
        ConfigError, match="--found-head-label must be one of .in-view., .seen., got .ever."
    ):
        Args(found_head=1.0, found_head_label="ever")


def test_a_seen_run_records_its_label_and_resumes_only_with_it(
    tmp_path: Path, room_dataset: Path
) -> None:
    args = tiny_args(tmp_path, room_dataset, frames=128, found_head=1.0, found_head_label="seen")
    train(args)
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert rows and all(math.isfinite(float(row["found_loss"])) for row in rows)  # labelled
    path = tmp_path / "run" / "checkpoint.pt"
    assert load_checkpoint(path)["args"]["found_head_label"] == "seen"
    policy, _, _ = load_policy(path)
    assert GOAL_VECTOR not in policy.sensors  # a label for training, never read to act
    longer = dataclasses.replace(args, frames=256, resume=True)
    with pytest.raises(CheckpointError, match=r"--found-head-label 'seen' \(this run asks for"):
        train(dataclasses.replace(longer, found_head_label="in-view"))
    assert train(longer)["frames"] == 256
