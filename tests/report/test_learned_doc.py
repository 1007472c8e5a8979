"""docs/learned.md leads with the central comparison (issue 31): its tables are what
`multion report` makes of the eval runs committed beside it, and those runs were made at the
reference's defaults (50-cell oracle crop, 3 × 3 goals, depth 0–10 m, 100 sampled val episodes)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from test_report import report

from multion_agents.report.document import BEGIN, END

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "learned.md"
RUNS = ROOT / "docs" / "learned" / "central"


def table_lines(text: str) -> list[str]:
    generated = text[text.index(BEGIN) : text.index(END)]
    return [line for line in generated.splitlines() if line.startswith("|")]


def test_doc_tables_are_the_reports_of_the_committed_runs(tmp_path: Path) -> None:
    runs = sorted(p.parent for p in RUNS.glob("*/metrics.json"))
    assert len(runs) >= 2, "docs/learned/central holds no comparison yet"
    shutil.copy(DOC, tmp_path / "learned.md")
    assert report([str(RUNS), "--out", str(tmp_path), "--doc", "learned", "--no-figures"]) == 0
    assert table_lines((tmp_path / "learned.md").read_text()) == table_lines(DOC.read_text())


@pytest.mark.parametrize("run", sorted(p.parent.name for p in RUNS.glob("*/metrics.json")))
def test_committed_runs_are_at_the_reference_defaults(run: str) -> None:
    recorded = json.loads((RUNS / run / "metrics.json").read_text())["run"]
    config = recorded["resolved_config"]
    assert (recorded["task"], recorded["split"], recorded["episodes"]) == ("1-on", "val", 100)
    assert (config["maps"]["ego_size"], config["maps"]["goal_cells"]) == (50, 3)
    assert (config["camera"]["min_depth"], config["camera"]["max_depth"]) == (0.0, 10.0)
    assert recorded["deterministic"] is False and recorded["seed"] == 0
    lines = (RUNS / run / "episodes.jsonl").read_text().splitlines()
    assert len(lines) == 100
