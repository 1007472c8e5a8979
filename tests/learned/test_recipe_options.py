"""The training options beyond the paper's recipe (issue 51): the goal heads and their targets,
the FOUND curriculum, vision pretraining, and that a resume keeps the options it was trained
with."""

from __future__ import annotations

import csv
import dataclasses
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from rollouts import SIZE
from rollouts import tiny_args as shared_tiny_args

from multion.config.codec import env_config_from_dict
from multion.config.datasets import load_dataset
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion.task.sensors import SENSOR_CLASSES, SensorInputs
from multion_agents.learned.checkpoint import (
    CheckpointError,
    check_recipe_options,
    load_checkpoint,
    load_policy,
)
from multion_agents.learned.goal_heads import (
    DIRECTION_BINS,
    GOAL_VECTOR,
    GoalHeads,
    direction_bin_centre,
    goal_targets,
)
from multion_agents.learned.rollout_envs import stage_config
from multion_agents.learned.train_options import FoundCurriculum, VisionPretraining
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_run import run_env_config, train
from multion_agents.learned.vision_frames import goal_in_view, sample_frames, view_labels
from multion_agents.learned.vision_pretrain import class_weights, pretrain_vision
from multion_client.constants import Action


def tiny_args(tmp_path: Path, dataset: Path, **changes: Any) -> Args:
    """``rollouts.tiny_args`` for no-map, 4 updates of 64 frames unless ``changes`` say."""
    values: dict[str, Any] = {"agent": "no-map", "frames": 256, "rollout_steps": 64, **changes}
    return shared_tiny_args(tmp_path, dataset, **values)


def assert_resumes_only_with(trained: Args, toggle: str) -> None:
    """A run ``trained`` with the boolean option ``toggle`` on: a resume with it off is refused,
    naming the option and both values, and a resume with the same options trains on."""
    longer = dataclasses.replace(trained, frames=2 * trained.frames, resume=True)
    flag = "--" + toggle.replace("_", "-")
    with pytest.raises(CheckpointError, match=rf"{flag} True \(this run asks for False\)"):
        train(dataclasses.replace(longer, **{toggle: False}))
    assert train(longer)["frames"] == longer.frames


# ---------------------------------------------------------------- goal heads: targets
def _vector(seen: float, bearing_deg: float, metres: float) -> torch.Tensor:
    return torch.tensor([[seen, math.radians(bearing_deg), metres]])


@pytest.mark.parametrize(
    ("bearing", "direction"),
    [(0, 0), (14.9, 0), (-14.9, 0), (15.1, 1), (44.9, 1), (-15.1, 11), (90, 3), (-90, 9),
     (179.9, 6), (-179.9, 6), (165.1, 6), (164.9, 5)],
)  # fmt: skip
def test_direction_bins_are_30_degrees_centred_on_ahead(bearing: float, direction: int) -> None:
    assert int(goal_targets(_vector(1, bearing, 2.0)).direction) == direction


@pytest.mark.parametrize(
    ("metres", "distance"), [(0.0, 0), (0.79, 0), (0.81, 1), (2.5, 3), (27.9, 34), (100.0, 34)]
)
def test_distance_bins_are_map_cells_of_08_m_capped_at_35(metres: float, distance: int) -> None:
    assert int(goal_targets(_vector(1, 0, metres)).distance) == distance


def test_bin_centres_invert_the_bins() -> None:
    for index in range(DIRECTION_BINS):
        centre = math.degrees(direction_bin_centre(index))
        assert int(goal_targets(_vector(1, centre, 1.0)).direction) == index


def _inputs(position, yaw: float, goal, seen: bool = False) -> SensorInputs:
    return SensorInputs(
        frame=None,
        goal_category=0,
        distance_to_goal=0.0,
        position=np.asarray(position, dtype=np.float64),
        yaw=yaw,
        start_position=np.zeros(2),
        start_yaw=0.0,
        oracle=None,
        goal_position=np.asarray(goal, dtype=np.float64),
        goal_seen=seen,
    )


@pytest.mark.parametrize(
    ("position", "yaw", "goal", "bearing", "metres"),
    [
        ((0, 0), 0.0, (2, 0), 0.0, 2.0),  # straight ahead
        ((0, 0), 0.0, (0, 2), 90.0, 2.0),  # on the left (yaw counter-clockwise)
        ((0, 0), math.pi / 2, (0, 2), 0.0, 2.0),  # turned to face it
        ((1, 1), 0.0, (1, -2), -90.0, 3.0),  # on the right
        ((0, 0), 0.0, (-3, 4), 180 - math.degrees(math.atan2(4, 3)), 5.0),
    ],
)
def test_the_goal_vector_of_hand_made_poses(position, yaw, goal, bearing, metres) -> None:
    seen, observed_bearing, distance = SENSOR_CLASSES[GOAL_VECTOR].observe(
        _inputs(position, yaw, goal, seen=True)
    )
    assert seen == 1.0
    assert math.degrees(observed_bearing) == pytest.approx(bearing, abs=1e-4)
    assert distance == pytest.approx(metres, abs=1e-5)


def test_the_env_marks_the_goal_seen_once_it_has_been_in_view(room_dataset: Path) -> None:
    """In the empty room every goal is within 6 m: a full turn brings it into view, and it stays
    seen when the agent turns away; bearing and distance follow the agent's pose."""
    config = EnvConfig(task=TaskConfig(num_goals=1), sensors=(GOAL_VECTOR,))
    episodes = load_dataset(room_dataset)
    env = MultiONEnv(config, episodes=episodes)
    try:
        observation, _ = env.reset(seed=0)
        goal = np.asarray(env.episode.goals[0].position[:2])  # type: ignore[union-attr]
        seen = [float(observation[GOAL_VECTOR][0])]
        for _ in range(24):  # two full turns
            observation, *_ = env.step(int(Action.TURN_LEFT))
            vector = observation[GOAL_VECTOR]
            seen.append(float(vector[0]))
            offset = goal - env.sim.position
            assert vector[2] == pytest.approx(np.hypot(*offset), abs=1e-4)
            expected = math.remainder(math.atan2(offset[1], offset[0]) - env.sim.yaw, 2 * math.pi)
            assert math.remainder(float(vector[1]) - expected, 2 * math.pi) == pytest.approx(
                0.0, abs=1e-4
            )
        assert seen[-1] == 1.0
        first = seen.index(1.0)
        assert all(value == 1.0 for value in seen[first:])  # once seen, seen for the episode
    finally:
        env.close()


def test_goal_losses_skip_direction_and_distance_until_the_goal_is_seen() -> None:
    torch.manual_seed(0)
    heads = GoalHeads(8)
    core = torch.randn(4, 8)
    unseen = torch.tensor([[0.0, 0.3, 2.0]] * 4)
    losses = heads.losses(core, unseen)
    assert float(losses.direction) == 0.0 and float(losses.distance) == 0.0
    assert float(losses.seen.detach()) == pytest.approx(
        float(
            torch.nn.functional.cross_entropy(
                heads.seen(core), torch.zeros(4, dtype=torch.long)
            ).detach()
        )
    )
    vectors = torch.tensor([[1.0, 0.0, 1.0], [0.0, 0.0, 1.0], [1.0, math.pi / 2, 3.0], [0, 0, 0]])
    losses = heads.losses(core, vectors)
    rows = torch.tensor([0, 2])
    expected = torch.nn.functional.cross_entropy(heads.direction(core[rows]), torch.tensor([0, 3]))
    assert float(losses.direction.detach()) == pytest.approx(float(expected.detach()))
    assert float(losses.seen_share) == pytest.approx(0.5)


# ---------------------------------------------------------------- goal heads: training, eval
def test_goal_heads_train_and_are_absent_when_the_checkpoint_acts(
    tmp_path: Path, room_dataset: Path
) -> None:
    train(tiny_args(tmp_path, room_dataset, goal_heads=True))
    path = tmp_path / "run" / "checkpoint.pt"
    payload = load_checkpoint(path)
    assert any(key.startswith("goal_heads.") for key in payload["model"])
    assert GOAL_VECTOR in payload["env_config"]["sensors"]
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert all(math.isfinite(float(row["goal_seen_loss"])) for row in rows)
    # the first update measures each term's gradient on the GRU, the next ones do not
    assert float(rows[0]["gru_gradient_goal_heads"]) > 0
    assert float(rows[0]["gru_gradient_policy"]) > 0 and rows[1]["gru_gradient_policy"] == ""
    policy, _, model = load_policy(path)
    assert model == "no-map" and policy.goal_heads is None
    assert GOAL_VECTOR not in policy.sensors and GOAL_VECTOR not in policy.train_sensors
    assert not any(key.startswith("goal_heads.") for key in policy.state_dict())


def test_without_goal_heads_nothing_changes(tmp_path: Path, room_dataset: Path) -> None:
    config = run_env_config(tiny_args(tmp_path, room_dataset))
    assert GOAL_VECTOR not in config.sensors
    with_heads = run_env_config(tiny_args(tmp_path, room_dataset, goal_heads=True))
    assert GOAL_VECTOR in with_heads.sensors


@pytest.mark.parametrize(
    ("agent", "option", "sensor"),
    [
        ("obj-recog-map", {"found_head": 1.0}, "goal_mask"),
        ("proj-neural-map", {"pose_input": True}, "gps"),
    ],
)
def test_an_option_asking_for_a_sensor_the_model_reads_gets_it_once(
    tmp_path: Path, room_dataset: Path, agent: str, option: dict[str, Any], sensor: str
) -> None:
    # learn-to-see's obj-recog-map stage: its recogniser and the FOUND head both read goal_mask
    config = run_env_config(tiny_args(tmp_path, room_dataset, agent=agent, **option))
    assert config.sensors.count(sensor) == 1


def test_a_resume_refuses_other_recipe_options(tmp_path: Path, room_dataset: Path) -> None:
    args = tiny_args(tmp_path, room_dataset, frames=128, goal_heads=True)
    train(args)
    longer = dataclasses.replace(args, frames=256, resume=True)
    with pytest.raises(CheckpointError, match=r"--goal-heads True \(this run asks for False\)"):
        train(dataclasses.replace(longer, goal_heads=False))
    found = FoundCurriculum(64, 1.0)
    with pytest.raises(CheckpointError, match="--found-curriculum"):
        train(dataclasses.replace(longer, found_curriculum=found))
    assert train(longer)["frames"] == 256  # the same options resume


def test_a_checkpoint_that_predates_the_options_counts_them_off(tmp_path: Path) -> None:
    recorded = {"agent": "no-map", "pretrain_map": {"steps": 0}}  # fields added later: defaults
    check_recipe_options(tmp_path / "old.pt", recorded, Args(agent="no-map"))
    with pytest.raises(CheckpointError, match="--pretrain-vision"):
        check_recipe_options(
            tmp_path / "old.pt",
            recorded,
            Args(agent="no-map", pretrain_vision=VisionPretraining(steps=10)),
        )


# ---------------------------------------------------------------- FOUND curriculum
def test_during_the_found_curriculum_a_wrong_found_costs_and_ends_nothing(
    room_dataset: Path,
) -> None:
    config = EnvConfig(task=TaskConfig(num_goals=1, slack_reward=-0.01), sensors=("goal",))
    found = FoundCurriculum(frames=1000, penalty=2.5)
    during, after = stage_config(config, (), 999, found), stage_config(config, (), 1000, found)
    assert after == config
    episodes = load_dataset(room_dataset)
    rewards = {}
    for name, stage in (("during", during), ("after", after)):
        env = MultiONEnv(stage, episodes=episodes)
        try:
            env.reset(seed=0)
            assert env.state is not None
            env.state.distance_to_goal = 99.0  # far from the goal: FOUND is wrong
            _, reward, terminated, _, _ = env.step(int(Action.FOUND))
            rewards[name] = (reward, terminated)
        finally:
            env.close()
    assert rewards["during"] == (pytest.approx(-2.51), False)
    assert rewards["after"] == (pytest.approx(-0.01), True)


def test_a_found_curriculum_run_switches_to_the_tasks_rule(
    tmp_path: Path, room_dataset: Path
) -> None:
    train(tiny_args(tmp_path, room_dataset, found_curriculum=FoundCurriculum(256, 2.5), frames=512))
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert [int(row["found_budget"]) for row in rows] == [100_000, 100_000, 0, 0]
    recorded = load_checkpoint(tmp_path / "run" / "checkpoint.pt")
    assert recorded["env_config"]["task"]["found_budget"] == 0  # the task's own, not the stage's
    assert recorded["args"]["found_curriculum"] == {"frames": 256, "penalty": 2.5}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("200000", "'200000' is not FRAMES:PENALTY"),
        ("x:1", "'x:1' is not FRAMES:PENALTY"),
        ("1000:-1", r"found_curriculum.penalty = -1.0 is out of range: allowed \[0, 1000\]"),
    ],
)
def test_train_cli_rejects_a_bad_found_curriculum(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    from multion_agents.cli import main

    code = main(["train", "--found-curriculum", text, "--frames", "64", "--out", str(tmp_path)])
    assert code == 2
    assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "checkpoint.pt").exists()


# ---------------------------------------------------------------- vision pretraining
def test_view_labels_place_each_category_by_the_centre_of_its_pixels() -> None:
    mask = np.zeros((9, 9), dtype=np.uint8)
    mask[4, 0:2] = 1  # category 0, left third
    mask[2:6, 4] = 4  # category 3, centre
    mask[0, 7:9] = 8  # category 7, right third
    labels = view_labels(mask)
    assert labels.tolist() == [1, 0, 0, 2, 0, 0, 0, 3]


def test_class_weights_balance_the_places() -> None:
    labels = np.array([[0] * 8, [0] * 7 + [1], [0] * 6 + [2, 3]])
    weights = class_weights(labels)
    counts = np.bincount(labels.reshape(-1), minlength=4)
    # each place's total weight is the same, and the mean weight over the labels is 1
    totals = weights.numpy() * counts
    assert totals == pytest.approx(np.full(4, totals[0]))
    assert float(weights[torch.as_tensor(labels.reshape(-1))].mean()) == pytest.approx(1.0)


def test_vision_pretraining_trains_the_encoder_on_frames_half_facing_the_goal(
    tmp_path: Path, room_dataset: Path
) -> None:
    config = run_env_config(tiny_args(tmp_path, room_dataset))
    settings = VisionPretraining(steps=100, samples=200, held_out=100, poses_per_scene=20)
    frames = sample_frames(config, 200, 0, settings)
    assert frames.rgb.shape == (200, SIZE, SIZE, 3) and frames.labels.shape == (200, 8)
    shown = goal_in_view(frames)
    assert shown[0::2].mean() > 0.6 > shown[1::2].mean()  # facing poses show it far more often
    from multion_agents.learned.models import build_policy

    policy = build_policy("no-map", config)
    before = {k: v.clone() for k, v in policy.state_dict().items()}
    scores = pretrain_vision(policy, config, settings, tmp_path, progress=False)
    after = policy.state_dict()
    changed = {k for k in before if not torch.equal(before[k], after[k])}
    assert changed and all(k.startswith("image_encoder.") for k in changed)
    assert sum(row.frames for row in scores) == 100
    rows = list(csv.DictReader((tmp_path / "pretrain_vision.csv").open()))
    assert int(rows[-1]["step"]) == 100


def test_vision_pretraining_needs_an_rgbd_agent(tmp_path: Path, room_dataset: Path) -> None:
    args = tiny_args(
        tmp_path, room_dataset, agent="only-oracle-map", pretrain_vision=VisionPretraining(10)
    )
    with pytest.raises(ValueError, match="--pretrain-vision trains the RGB-D encoder"):
        train(args)


def test_env_config_round_trips_with_the_new_sensor() -> None:
    config = env_config_from_dict({"sensors": ["rgb", GOAL_VECTOR]})
    assert config.sensors == ("rgb", GOAL_VECTOR)


# ---------------------------------------------------------------- multion diagnose
def test_diagnose_scores_seeing_and_found_calls_of_a_checkpoint(
    tmp_path: Path, room_dataset: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    from multion_agents.cli import main

    train(tiny_args(tmp_path, room_dataset, agent="obj-recog-map", frames=128))
    checkpoint = str(tmp_path / "run" / "checkpoint.pt")
    code = main(["diagnose", checkpoint, "--episodes", "2", "--probe-frames", "200",
                 "--held-out", "100", "--probe-steps", "20", "--out", str(tmp_path / "d"),
                 "--quiet"])  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    assert "a linear probe of the frozen image embedding" in printed
    assert "the agent's own recogniser" in printed and "episodes ended:" in printed
    result = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert result["model"] == "obj-recog-map"
    assert sum(row["frames"] for row in result["probe"]) == 100
    assert sum(row["frames"] for row in result["recogniser"]) == 100
    calls = result["found_calls"]
    assert sum(calls["endings"].values()) == 2
    assert calls["near_steps"] + calls["far_steps"] > 0
    assert calls["in_view_steps"] + calls["seen_out_of_view_steps"] <= calls["near_steps"]
    assert "out of view but seen earlier" in printed
    assert "camera (tiny)" in printed  # the config's renderer: the checkpoint's is not kept
    # the machine's renderer (auto: gl where a context opens, else tiny), as in `multion eval`
    code = main(["diagnose", checkpoint, "--episodes", "1", "--no-probe", "--renderer", "auto",
                 "--quiet"])  # fmt: skip
    assert code == 0 and "camera (auto)" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("flags", "message"),
    [(["--episodes", "0"], r"--episodes must be in \[1, 1000\]"),
     (["--probe-frames", "10"], "probe frames = 10 is out of range"),
     ([], "no such checkpoint file")],
)  # fmt: skip
def test_diagnose_names_a_bad_option_or_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flags: list[str], message: str
) -> None:
    from multion_agents.cli import main

    assert main(["diagnose", str(tmp_path / "missing.pt"), *flags]) == 2
    assert re.search(message, capsys.readouterr().err)


def test_diagnose_names_the_renderers_it_takes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from multion_agents.cli import main

    with pytest.raises(SystemExit) as exited:
        main(["diagnose", str(tmp_path / "missing.pt"), "--renderer", "vulkan"])
    assert exited.value.code == 2
    assert re.search(r"invalid choice: 'vulkan' \(choose from .*'tiny'", capsys.readouterr().err)


# ---------------------------------------------------------------- balanced recognition
def test_balancing_weights_give_each_present_class_the_same_total() -> None:
    from multion_agents.learned.learned_maps import balancing_weights

    label = torch.tensor([0, 0, 0, 0, 0, 0, 3, 3])
    weights = balancing_weights(label, 9)
    assert weights[0] * 6 == pytest.approx(float(weights[3] * 2))
    assert float(weights[label].mean()) == pytest.approx(1.0)
    assert float(weights[1]) == 0.0


def test_balanced_recognition_trains_obj_recog_map_only(tmp_path: Path, room_dataset: Path) -> None:
    args = tiny_args(tmp_path, room_dataset, agent="obj-recog-map", frames=128)
    train(dataclasses.replace(args, balanced_recognition=True))
    recorded = load_checkpoint(tmp_path / "run" / "checkpoint.pt")["args"]
    assert recorded["balanced_recognition"] is True
    with pytest.raises(ValueError, match="--balanced-recognition trains ObjRecogMap.s"):
        train(tiny_args(tmp_path / "other", room_dataset, balanced_recognition=True))
