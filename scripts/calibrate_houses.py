"""Check the procedural houses against Matterport3D: `random-oracle-found` vs the paper's
`Rand+OracleFound` (Table 3), and the houses' sizes.

The target (issue 12): on 1,000 packaged val episodes per task, Success and Progress within ±5
points of the paper's 26 / 8 / 2 % and 26 / 16 / 12 % for 1-, 2- and 3-ON. The agent needs only
the ``goal`` and ``goal_distance`` sensors, so nothing is rendered; episodes run in this process.

    .venv/bin/python scripts/calibrate_houses.py                       # the packaged val sets
    .venv/bin/python scripts/calibrate_houses.py --episodes 200        # quicker, wider intervals
    .venv/bin/python scripts/calibrate_houses.py --generate 150        # fresh episodes in the
                                                                       # current houses (no files
                                                                       # needed: for tuning)
    .venv/bin/python scripts/calibrate_houses.py --houses              # house sizes only
    .venv/bin/python scripts/calibrate_houses.py --from-runs DIR       # the table from existing
                                                                       # `multion eval` runs
                                                                       # DIR/random-oracle-found-Mon
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

PAPER = {  # Rand+OracleFound, Table 3 (Matterport3D test): (Success %, Progress %)
    1: (26.0, 26.0),
    2: (8.0, 16.0),
    3: (2.0, 12.0),
}
TOLERANCE = 5.0


def house_table(split: str) -> list[str]:
    """Rooms, footprint, navigable fraction and build time of the split's houses."""
    from multion.scenes.registry import scene_ids
    from multion.sim.house_measure import measure_house
    from multion.sim.simulator import Simulator

    lines = [f"{'scene':<12}{'rooms':>6}{'corr.':>6}{'doors':>6}{'m²':>7}{'nav m²':>8}"
             f"{'nav %':>7}{'build s':>9}"]  # fmt: skip
    sim = Simulator()
    try:
        measures = []
        for scene in scene_ids(split):
            h = measure_house(sim, scene)
            measures.append(h)
            lines.append(
                f"{scene:<12}{h.rooms:>6}{h.corridors:>6}{h.doors:>6}{h.footprint_m2:>7.0f}"
                f"{h.navigable_m2:>8.0f}{100 * h.navigable_share:>7.1f}{h.build_s:>9.1f}"
            )
    finally:
        sim.close()
    areas = [h.footprint_m2 for h in measures]
    fractions = [h.navigable_share for h in measures]
    lines.append(
        f"mean footprint {np.mean(areas):.0f} m² ({min(areas):.0f}–{max(areas):.0f}), "
        f"navigable {100 * np.mean(fractions):.1f} % ({100 * min(fractions):.1f}–"
        f"{100 * max(fractions):.1f}), build {np.mean([h.build_s for h in measures]):.1f} s "
        "per house (first build; includes the navigable grid)"
    )
    return lines


def row(m: int, success, progress, count: int, seconds: float) -> tuple[str, bool]:
    paper_s, paper_p = PAPER[m]
    good = (
        abs(100 * success.mean - paper_s) <= TOLERANCE
        and abs(100 * progress.mean - paper_p) <= TOLERANCE
    )
    text = (
        f"{m}-ON  {count:>6}  "
        f"{100 * success.mean:5.1f} [{100 * success.low:4.1f}, {100 * success.high:4.1f}]"
        f"  {paper_s:5.0f}  "
        f"{100 * progress.mean:5.1f} [{100 * progress.low:4.1f}, {100 * progress.high:4.1f}]"
        f"  {paper_p:5.0f}  {'yes' if good else 'NO':>4}  {seconds:6.0f}"
    )
    return text, good


HEADER = "task  episodes  Success % [95% CI]     paper  Progress % [95% CI]    paper  ±5?  seconds"


def from_runs(runs: Path, tasks: list[int]) -> bool:
    """The table from ``multion eval`` output folders (their metrics.json)."""
    import json
    from types import SimpleNamespace

    rows, ok = [], True
    for m in tasks:
        data = json.loads((runs / f"random-oracle-found-{m}on" / "metrics.json").read_text())
        metrics = data["metrics"]
        success, progress = (SimpleNamespace(**metrics[k]) for k in ("success", "progress"))
        text, good = row(m, success, progress, metrics["episodes"], data["run"]["seconds"])
        rows.append(text)
        ok &= good
    print(HEADER)
    print("\n".join(rows))
    return ok


def calibrate(
    tasks: list[int], episodes: int, generate: int, seed: int, workers: int, out: Path | None
) -> bool:
    """Play random-oracle-found on val in this process (houses are built once for all tasks)."""
    from multion.task.generate import generate_dataset
    from multion_agents.evaluate import EvalSettings, evaluate
    from multion_agents.report.run_summary import write_report
    from multion_agents.report.stats import bootstrap

    rows, ok = [], True
    with tempfile.TemporaryDirectory() as tmp:
        for m in tasks:
            dataset = None
            if generate:
                dataset = str(Path(tmp) / f"{m}-on.json.gz")
                generate_dataset(dataset, m, "val", generate, seed=1000 + m, progress=False)
            settings = EvalSettings(
                agent="random-oracle-found", num_goals=m, split="val",
                episodes=None if generate else episodes, seed=seed, in_process=True,
                workers=workers, dataset=dataset,
            )  # fmt: skip
            tick = time.perf_counter()
            result = evaluate(settings, progress=False)
            took = time.perf_counter() - tick
            if out is not None:  # the same files as `multion eval --out`
                write_report(result, out / f"random-oracle-found-{m}on", pictures=0)
            success = bootstrap([float(r.metrics["success"]) for r in result.records])
            progress = bootstrap([float(r.metrics["progress"]) for r in result.records])
            text, good = row(m, success, progress, len(result.records), took)
            ok &= good
            rows.append(text)
            print(text, flush=True)
    print()
    print(HEADER)
    print("\n".join(rows))
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, nargs="*", default=[1, 2, 3])
    parser.add_argument(
        "--episodes",
        type=int,
        default=1000,
        help="evenly spaced packaged val episodes per task (default 1000)",
    )
    parser.add_argument(
        "--generate",
        type=int,
        default=0,
        help="instead, play this many freshly generated val episodes per task",
    )
    parser.add_argument("--seed", type=int, default=0, help="the agent's seed")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--houses", action="store_true", help="print the val houses' sizes only")
    parser.add_argument(
        "--out", type=Path, help="also write each task's run to OUT/random-oracle-found-Mon/"
    )
    parser.add_argument(
        "--from-runs",
        type=Path,
        help="read DIR/random-oracle-found-Mon/metrics.json instead of playing",
    )
    args = parser.parse_args()
    if args.from_runs is not None:
        return 0 if from_runs(args.from_runs, args.tasks) else 1
    if args.houses:
        print("\n".join(house_table("val")))
        return 0
    ok = calibrate(args.tasks, args.episodes, args.generate, args.seed, args.workers, args.out)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
