"""The report's training curves: drawn from a learned run's `progress.csv` (in its run directory
or beside it), keeping only the training that a resume kept and full success windows."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest
from PIL import Image
from test_report import report

from multion_agents.learned.training_log import read_csv
from multion_agents.report.figures import full_windows
from multion_agents.report.runs import load_run


def write_log(path: Path, rows: list[tuple[int, int, int, float]]) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["update", "frames", "episodes", "train_success"])
        writer.writerows(rows)


def as_learned(run: Path) -> None:
    """Mark a copied baseline run as played from a checkpoint (only learned runs have logs)."""
    metrics = json.loads((run / "metrics.json").read_text())
    metrics["run"]["checkpoint"] = f"runs/{run.name}/checkpoint.pt"
    (run / "metrics.json").write_text(json.dumps(metrics))


def test_resumed_rows_and_partial_windows_are_left_out(tmp_path: Path) -> None:
    log = tmp_path / "progress.csv"
    # updates 1-4 with a full window of 100; interrupted after 4, resumed from 3's checkpoint:
    # its window refills (3 then 100 episodes)
    write_log(
        log,
        [(1, 1024, 40, 0.0), (2, 2048, 100, 0.1), (3, 3072, 100, 0.2), (4, 4096, 100, 0.3)]
        + [(4, 4096, 3, 1.0), (5, 5120, 100, 0.4)],
    )
    kept = full_windows(read_csv(log))
    assert [(r["update"], r["train_success"]) for r in kept] == [(2, 0.1), (3, 0.2), (5, 0.4)]


def test_training_curves_figure(report_runs: Path, tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    beside = runs / "learned-beside" / "eval-val"  # multion train --out X; eval --out X/eval-val
    inside = runs / "learned-inside"
    shutil.copytree(report_runs / "oracle-planner-1on", beside)
    shutil.copytree(report_runs / "random-oracle-found-1on", inside)
    shutil.copytree(report_runs / "oracle-planner-2on", runs / "baseline")
    for run in (beside, inside):
        as_learned(run)
    write_log(beside.parent / "progress.csv", [(1, 1024, 100, 0.1), (2, 2048, 100, 0.5)])
    write_log(inside / "progress.csv", [(1, 1024, 100, 0.2)])
    assert load_run(beside).training_log == beside.parent / "progress.csv"
    assert load_run(inside).training_log == inside / "progress.csv"
    assert load_run(runs / "baseline").training_log is None
    out = tmp_path / "report"
    assert report([str(beside), str(inside), str(runs / "baseline"), "--out", str(out)]) == 0
    with Image.open(out / "training-curves.png") as image:
        image.verify()
    assert "![Training curves](training-curves.png)" in (out / "report.md").read_text()


def test_no_training_logs_no_figure(report_runs: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    assert report([str(report_runs / "oracle-planner-1on"), "--out", str(out)]) == 0
    assert not (out / "training-curves.png").exists()
    pytest.importorskip("matplotlib")
    assert (out / "metrics-vs-m.png").exists()
