"""The scripts in scripts/ run (they import from the packages, and moves there broke them once)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PYTHON_SCRIPTS = sorted((ROOT / "scripts").glob("*.py"))


def run(*args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *args], cwd=ROOT, capture_output=True, text=True, timeout=timeout
    )


@pytest.mark.parametrize("script", PYTHON_SCRIPTS, ids=lambda p: p.name)
def test_every_script_answers_help(script: Path) -> None:
    done = run(str(script), "--help", timeout=120)
    assert done.returncode == 0, done.stderr
    assert "usage:" in done.stdout


def test_the_calibration_plays_and_reads_its_runs(tmp_path: Path) -> None:
    played = run("scripts/calibrate_houses.py", "--tasks", "1", "--episodes", "2",
                 "--out", str(tmp_path))  # fmt: skip
    assert played.returncode in (0, 1), played.stderr  # 1: outside the band (2 episodes)
    assert (tmp_path / "random-oracle-found-1on" / "metrics.json").is_file()
    table = run("scripts/calibrate_houses.py", "--tasks", "1", "--from-runs", str(tmp_path))
    assert table.returncode in (0, 1), table.stderr
    row = next(line for line in table.stdout.splitlines() if line.lstrip().startswith("1"))
    assert "26" in row  # the paper's Rand+OracleFound 1-ON figure beside ours
