"""A bad ``--out`` is refused before any long work starts, naming the path (issue 42: a dangling
``runs`` link made ``multion eval`` die with FileExistsError after minutes of evaluation)."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from multion_agents import cli_eval, cli_report, evaluate
from multion_agents.files import output_directory_problem


def _dangling_link(tmp_path: Path) -> Path:
    link = tmp_path / "runs"
    link.symlink_to(tmp_path / "elsewhere" / "runs")
    return link


def test_a_dangling_link_a_file_in_the_way_and_a_read_only_parent_are_named(
    tmp_path: Path,
) -> None:
    link = _dangling_link(tmp_path)
    problem = output_directory_problem(link / "eval-oracle-planner")
    assert problem is not None and str(link) in problem and "does not exist" in problem
    (tmp_path / "file").write_text("x")
    problem = output_directory_problem(tmp_path / "file" / "out")
    assert problem is not None and "is not a directory" in problem
    assert output_directory_problem(tmp_path / "new" / "deeper") is None
    assert not (tmp_path / "new").exists()  # nothing is created by the check


def test_eval_refuses_the_out_directory_before_evaluating(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def must_not_run(*_: object, **__: object) -> None:
        raise AssertionError("the evaluation started before --out was checked")

    monkeypatch.setattr(evaluate, "evaluate", must_not_run)
    link = _dangling_link(tmp_path)
    parser = argparse.ArgumentParser()
    cli_eval.add_arguments(parser)
    args = parser.parse_args(["--agent", "random", "--quiet", "--out", str(link / "eval")])
    assert cli_eval.run(args) == 2
    err = capsys.readouterr().err
    assert f"--out {link / 'eval'}" in err and "does not exist" in err


def test_report_refuses_the_out_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    link = _dangling_link(tmp_path)
    parser = argparse.ArgumentParser()
    cli_report.add_arguments(parser)
    args = parser.parse_args([str(tmp_path), "--out", str(link / "report"), "--no-figures"])
    assert cli_report.run(args) == 2
    assert "does not exist" in capsys.readouterr().err


def test_metrics_json_names_a_packaged_dataset_without_this_machines_path(tmp_path: Path) -> None:
    import json

    parser = argparse.ArgumentParser()
    cli_eval.add_arguments(parser)
    argv = ["--agent", "random", "--task", "1-on", "--episodes", "1", "--in-process"]
    args = parser.parse_args([*argv, "--max-steps", "3", "--quiet", "--out", str(tmp_path / "o")])
    assert cli_eval.run(args) == 0
    run = json.loads((tmp_path / "o" / "metrics.json").read_text())["run"]
    assert run["server"]["dataset"]["path"] == "packaged:1-on/val.json.gz"
