"""Print the Markdown table of docs/baselines.md from runs/baselines/AGENT-Mon/metrics.json.

.venv/bin/python scripts/baselines_table.py [RUNS_DIR]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

AGENTS = ("random", "random-oracle-found", "oracle-planner", "explorer")
METRICS = ("success", "progress", "spl", "ppl")
TASKS = (("1-ON", "1on"), ("2-ON", "2on"), ("3-ON", "3on"), ("3-ON + 3 distractors", "3on-distractors"))


def cell(estimate: dict[str, float]) -> str:
    """``mean [low, high]`` in percent."""
    return (
        f"{100 * estimate['mean']:.1f} [{100 * estimate['low']:.1f}, {100 * estimate['high']:.1f}]"
    )


def main(runs: Path) -> None:
    print(
        "| agent | task | episodes | Success % | Progress % | SPL % | PPL % | steps | end reasons |"
    )
    print("| --- | --- | ---: | --- | --- | --- | --- | ---: | --- |")
    for agent in AGENTS:
        for task, folder in TASKS:
            path = runs / f"{agent}-{folder}" / "metrics.json"
            if not path.exists():
                print(f"| {agent} | {task} | – | not run | | | | | |")
                continue
            metrics = json.loads(path.read_text())["metrics"]
            ends = ", ".join(f"{k} {v}" for k, v in sorted(metrics["end_reasons"].items()))
            cells = " | ".join(cell(metrics[k]) for k in METRICS)
            print(
                f"| {agent} | {task} | {metrics['episodes']} | {cells} | "
                f"{metrics['mean_steps']:.0f} | {ends} |"
            )


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("runs/baselines"))
