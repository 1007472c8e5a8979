"""``progress.csv`` (:class:`TrainingLog`): rows appended under one header; a column that
appears later (a resumed run from newer code, a measurement made every 10th update) widens the
header instead of being dropped."""

from __future__ import annotations

import csv
from pathlib import Path

from multion_agents.learned.training_log import TrainingLog


def _read(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        return list(reader.fieldnames or []), list(reader)


def test_rows_share_the_first_rows_columns(tmp_path: Path) -> None:
    log = TrainingLog(tmp_path, tensorboard=False)
    log.write("progress", {"update": 0, "frames": 64, "loss": 0.1234567891})
    log.write("progress", {"update": 1, "frames": 128})
    columns, rows = _read(tmp_path / "progress.csv")
    assert columns == ["update", "frames", "loss"]
    assert rows[0]["loss"] == "0.123457" and rows[1]["loss"] == ""


def test_a_new_column_widens_the_header_and_keeps_every_earlier_row(tmp_path: Path) -> None:
    log = TrainingLog(tmp_path, tensorboard=False)
    for update in range(3):
        log.write("progress", {"update": update, "frames": 64 * (update + 1), "loss": 0.5})
    # a resumed run whose code logs a column the file's first row did not have
    log = TrainingLog(tmp_path, tensorboard=False)
    log.write("progress", {"update": 3, "frames": 256, "gru_gradient_policy": 0.02, "loss": 0.4})
    log.write("progress", {"update": 4, "frames": 320, "loss": 0.3})
    columns, rows = _read(tmp_path / "progress.csv")
    assert columns == ["update", "frames", "loss", "gru_gradient_policy"]
    assert [row["update"] for row in rows] == ["0", "1", "2", "3", "4"]
    assert [row["gru_gradient_policy"] for row in rows] == ["", "", "", "0.02", ""]
    assert [row["loss"] for row in rows] == ["0.5", "0.5", "0.5", "0.4", "0.3"]
    assert [path.name for path in tmp_path.iterdir()] == ["progress.csv"]  # no temporary left


def test_rewind_after_widening_keeps_the_wide_header(tmp_path: Path) -> None:
    log = TrainingLog(tmp_path, tensorboard=False)
    log.write("progress", {"update": 0, "frames": 64})
    log.write("progress", {"update": 1, "frames": 128, "advantage_std": 0.4})
    log.write("progress", {"update": 2, "frames": 192, "advantage_std": 0.3})
    log.rewind(1)
    columns, rows = _read(tmp_path / "progress.csv")
    assert columns == ["update", "frames", "advantage_std"]
    assert [(row["update"], row["advantage_std"]) for row in rows] == [("0", ""), ("1", "0.4")]
