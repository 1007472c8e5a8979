"""``multion rescore``: a run's recorded actions played again without its agent; every recorded
metric must come out the same before the measures the run lacks are added."""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
from pathlib import Path

import pytest

from multion.config.episode import Episode
from multion_agents import cli_eval, cli_rescore

ADDED = "current_goal_seen"


def _run(module: object, argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    module.add_arguments(parser)  # type: ignore[attr-defined]
    return int(module.run(parser.parse_args(argv)))  # type: ignore[attr-defined]


def _lines(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def evaluated(
    room_dataset: tuple[Path, list[Episode]], tmp_path_factory: pytest.TempPathFactory
) -> Path:
    """A 3-episode run of the random agent (FOUND a quarter of the time: every ending)."""
    out = tmp_path_factory.mktemp("rescore") / "run"
    argv = [
        "--agent", "random", "--task", "1-on", "--dataset", str(room_dataset[0]),
        "--in-process", "--max-steps", "40", "--image-size", "16", "--pictures", "0",
        "--quiet", "--out", str(out),
    ]  # fmt: skip
    with contextlib.redirect_stdout(io.StringIO()):
        assert _run(cli_eval, argv) == 0
    return out


def _older(evaluated: Path, to: Path) -> Path:
    """The run as a version of the task without ``current_goal_seen`` would have written it."""
    shutil.copytree(evaluated, to)
    lines = _lines(to)
    for line in lines:
        del line["metrics"][ADDED]
    (to / "episodes.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    return to


def test_a_run_gains_the_measures_it_lacked_and_keeps_the_rest(
    evaluated: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    older = _older(evaluated, tmp_path / "older")
    before = (older / "episodes.jsonl").read_text()
    assert _run(cli_rescore, [str(older), "--check", "--quiet"]) == 0
    assert "would add current_goal_seen" in capsys.readouterr().out
    assert (older / "episodes.jsonl").read_text() == before  # --check writes nothing
    assert _run(cli_rescore, [str(older), "--quiet"]) == 0
    assert "3 episodes replayed as recorded; added current_goal_seen" in capsys.readouterr().out
    # the same lines as a fresh evaluation, the recorded values untouched
    assert _lines(older) == _lines(evaluated)
    metrics = json.loads((older / "metrics.json").read_text())
    assert metrics["run"]["rescored"][0]["added"] == [ADDED]
    # a second pass has nothing to add and writes nothing
    assert _run(cli_rescore, [str(older), "--quiet"]) == 0
    assert "no measure to add" in capsys.readouterr().out
    assert len(json.loads((older / "metrics.json").read_text())["run"]["rescored"]) == 1


def test_a_run_whose_replay_differs_is_left_as_it_was(
    evaluated: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    changed = _older(evaluated, tmp_path / "changed")
    lines = _lines(changed)
    lines[1]["metrics"]["steps"] += 1  # a record the replay cannot reproduce
    (changed / "episodes.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    before = (changed / "episodes.jsonl").read_text(), (changed / "metrics.json").read_text()
    assert _run(cli_rescore, [str(changed), "--quiet"]) == 2
    error = capsys.readouterr().err
    assert lines[1]["episode_id"] in error and "steps" in error
    assert ((changed / "episodes.jsonl").read_text(), (changed / "metrics.json").read_text()) == (
        before
    )


def test_actions_that_outlast_the_episode_are_refused(
    evaluated: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    longer = _older(evaluated, tmp_path / "longer")
    lines = _lines(longer)
    lines[0]["actions"] += "1"
    (longer / "episodes.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    assert _run(cli_rescore, [str(longer), "--quiet"]) == 2
    assert "the replay ended after" in capsys.readouterr().err


def test_a_directory_that_is_no_run_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _run(cli_rescore, [str(tmp_path / "missing"), "--quiet"]) == 2
    assert "missing" in capsys.readouterr().err


def test_a_run_without_recorded_actions_is_refused(
    evaluated: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    silent = _older(evaluated, tmp_path / "silent")
    lines = _lines(silent)
    for line in lines:
        del line["actions"]
    (silent / "episodes.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    assert _run(cli_rescore, [str(silent), "--quiet"]) == 2
    assert "no recorded actions" in capsys.readouterr().err
