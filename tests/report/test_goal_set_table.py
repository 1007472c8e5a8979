"""The report's goal-set table (the supplement's NoMap colour vs shape, tab:color_vs_shape):
runs that differ only in ``task.goal_set`` side by side, their paired difference, the paper's
numbers beside them, and never a pair across goal sets in the general comparisons."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_report import METRICS, episodes, report, run_eval

from multion_agents.report.paper import paper_results


@pytest.fixture(scope="module")
def goal_set_runs(report_runs: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """oracle-planner and random-oracle-found on the 1-ON episodes with coloured cylinders
    (copied from the shared runs) and random-oracle-found again with the supplement's shapes."""
    root = tmp_path_factory.mktemp("goal-set-runs")
    for name in ("oracle-planner-1on", "random-oracle-found-1on"):
        shutil.copytree(report_runs / name, root / name)
    recorded = json.loads((root / "random-oracle-found-1on" / "metrics.json").read_text())["run"]
    argv = ["--agent", "random-oracle-found", "--task", "1-on", "--max-steps", "80"]
    argv += ["--in-process", "--pictures", "0", "--quiet", "--image-size", "16"]
    argv += ["--dataset", recorded["dataset"], "--set", "task.goal_set=shapes"]
    assert run_eval([*argv, "--out", str(root / "random-oracle-found-1on-shapes")]) == 0
    return root


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_goal_set_rows_and_paired_difference(goal_set_runs: Path, tmp_path: Path) -> None:
    assert report([str(goal_set_runs), "--out", str(tmp_path), "--no-figures"]) == 0
    rows = read_csv(tmp_path / "goal-sets.csv")
    colours, shapes = (
        goal_set_runs / "random-oracle-found-1on",
        goal_set_runs / ("random-oracle-found-1on-shapes"),
    )
    # oracle-planner has one goal set only: it gets no rows
    assert [(r["run"], r["goal_set"]) for r in rows] == [
        ("random-oracle-found-1on", "colours"),
        ("random-oracle-found-1on-shapes", "shapes"),
        ("random-oracle-found-1on-shapes − random-oracle-found-1on", "shapes − colours (paired)"),
    ]
    a = {e["episode_id"]: e["metrics"] for e in episodes(shapes)}
    b = {e["episode_id"]: e["metrics"] for e in episodes(colours)}
    assert set(a) == set(b) and int(rows[2]["episodes"]) == len(a)
    for metric in METRICS:
        assert float(rows[0][metric]) == pytest.approx(
            100 * np.mean([m[metric] for m in b.values()])
        )
        assert float(rows[1][metric]) == pytest.approx(
            100 * np.mean([m[metric] for m in a.values()])
        )
        by_hand = 100 * np.mean([a[i][metric] - b[i][metric] for i in a])
        assert float(rows[2][f"diff_{metric}"]) == pytest.approx(by_hand, abs=1e-3)
    # across goal sets the general comparisons do not pair runs, and Table 3 gives the paper's
    # colour row only to the colour run
    paired = read_csv(tmp_path / "paired.csv")
    assert {(r["run_a"], r["run_b"]) for r in paired} == {
        ("random-oracle-found-1on", "oracle-planner-1on")
    } or {(r["run_b"], r["run_a"]) for r in paired} == {
        ("random-oracle-found-1on", "oracle-planner-1on")
    }
    table3 = {r["run"]: r for r in read_csv(tmp_path / "table3.csv")}
    assert table3["random-oracle-found-1on"]["paper_success"] == "26.0"
    assert table3["random-oracle-found-1on-shapes"]["paper_success"] == ""
    assert table3["random-oracle-found-1on-shapes"]["goal set"] == "shapes"
    text = (tmp_path / "report.md").read_text()
    assert "## Goal sets" in text and "random-oracle-found (goal set shapes)" in text


def test_paper_colour_vs_shape_numbers() -> None:
    """The supplement's tab:color_vs_shape (multion-neurips2020.tex l. 1016-1017), NoMap only."""
    paper = paper_results()
    assert paper.goal_set_row("no-map", 1, "colours") == {
        "success": 62.0,
        "progress": 62.0,
        "spl": 35.0,
        "ppl": 35.0,
    }
    assert paper.goal_set_row("no-map", 3, "shapes") == {
        "success": 0.0,
        "progress": 5.0,
        "spl": 0.0,
        "ppl": 4.0,
    }
    assert paper.goal_set_row("oracle-map", 1, "shapes") is None
    assert paper.goal_set_row("no-map", 4, "shapes") is None
    assert paper.goal_set_row("no-map", 1, "objects") is None
