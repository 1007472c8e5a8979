"""A training run as an object (issue 45 item 3): ``TrainingRun.start`` / ``resume``, one
``update()`` at a time, after-update hooks in order, the val evaluation passed in."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import pytest
from rollouts import tiny_args

from multion.config.task import EnvConfig
from multion_agents.learned.checkpoint import load_checkpoint
from multion_agents.learned.policy import RecurrentPolicy
from multion_agents.learned.rollout_envs import SUMMARY_METRICS
from multion_agents.learned.training_run import TrainingRun


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as handle:
        return list(csv.DictReader(handle))


def test_a_run_updates_one_step_at_a_time_and_calls_its_hooks_in_order(
    tmp_path: Path, room_dataset: Path
) -> None:
    # 2 envs x 32 steps = 64 frames an update: 3 updates; checkpoints after updates 2 and 3
    # (the last), evaluations when the frames cross 128 (update 2) and after the last
    args = tiny_args(
        tmp_path, room_dataset, frames=192, checkpoint_every=2, eval_every=128, eval_episodes=1
    )
    evaluated: list[tuple[RecurrentPolicy, EnvConfig]] = []

    def evaluation(policy: RecurrentPolicy, env_config: EnvConfig) -> dict[str, float]:
        evaluated.append((policy, env_config))
        return {k: 0.5 for k in SUMMARY_METRICS}

    seen: list[tuple[int, bool, int]] = []

    def after_update(run: TrainingRun, summary: dict[str, Any]) -> None:
        saved = (run.out / "checkpoint.pt").is_file()
        seen.append((summary["update"], saved, len(evaluated)))

    with TrainingRun.start(args, evaluation) as run:
        run.hooks.append(after_update)
        assert (run.total_updates, run.updates, run.done) == (3, 0, False)
        first = run.update()
        assert first["update"] == 1 and first["frames"] == 64 and run.frames == 64
        while not run.done:
            run.update()
        summary = run.finish()

    assert seen == [(1, False, 0), (2, True, 1), (3, True, 2)]
    # the evaluation gets the live policy and the run's own (train) config
    assert all(policy is run.policy for policy, _ in evaluated)
    assert {(c.split, c.task.max_steps, c.dataset) for _, c in evaluated} == {
        ("train", 40, str(room_dataset))
    }
    out = tmp_path / "run"
    rows = _rows(out / "progress.csv")
    assert [int(r["update"]) for r in rows] == [1, 2, 3]
    # how the training episodes ended: a found goal was within reach
    assert {"train_within_reach", "train_wrong_found"} <= set(rows[0])
    ended = [r for r in rows if float(r["episodes"]) > 0]
    assert all(float(r["train_within_reach"]) >= float(r["train_success"]) for r in ended)
    assert [(int(r["frames"]), float(r["success"])) for r in _rows(out / "eval.csv")] == [
        (128, 0.5),
        (192, 0.5),
    ]
    checkpoint = load_checkpoint(out / "checkpoint.pt")
    assert (checkpoint["update"], checkpoint["frames"]) == (3, 192) == (run.updates, run.frames)
    assert summary["frames"] == 192 and summary["update"] == 3 and "weights_sha256" in summary


def test_a_resumed_run_starts_at_the_checkpoint_and_may_already_be_done(
    tmp_path: Path, room_dataset: Path
) -> None:
    with TrainingRun.start(tiny_args(tmp_path, room_dataset, frames=64)) as run:
        run.update()
        assert run.done
    resumed = TrainingRun.resume(tiny_args(tmp_path, room_dataset, frames=128, resume=True))
    with resumed:
        assert (resumed.updates, resumed.frames, resumed.done) == (1, 64, False)
        assert resumed.update()["update"] == 2
        assert resumed.done
    with TrainingRun.resume(tiny_args(tmp_path, room_dataset, frames=128, resume=True)) as again:
        assert again.done and again.finish()["frames"] == 128


def test_evaluation_episodes_without_an_evaluation_fail_before_anything_starts(
    tmp_path: Path, room_dataset: Path
) -> None:
    args = tiny_args(tmp_path, room_dataset, eval_episodes=2)
    with pytest.raises(ValueError, match="eval_episodes is 2 but no evaluation"):
        TrainingRun.start(args)
    assert not (tmp_path / "run").exists()
