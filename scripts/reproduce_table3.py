"""Reproduce the paper's Table 3: train every agent on 1-, 2- and 3-ON, evaluate on test, and
write our table beside the paper's. Resumable: run it again and finished steps are skipped,
interrupted trainings continue from their checkpoint.

    .venv/bin/python scripts/reproduce_table3.py                       # the paper's budget
    .venv/bin/python scripts/reproduce_table3.py --estimate-only       # time per run, then stop
    .venv/bin/python scripts/reproduce_table3.py --frames 2048 --envs 2 --image-size 64 \\
        --episodes 3 --eval-max-steps 200 --agents no-map oracle-map --out runs/table3-small

First it builds the navigable grids of the train and test houses into the disk cache (once per
machine), then measures this machine's training speed for each agent (two short PPO updates
with the run's settings) and prints how long each run would take. Layout of ``--out``:
``AGENT/TASK/checkpoint.pt`` (``multion train``), ``AGENT/TASK/test/metrics.json``
(``multion eval``), and ``table3.md`` / ``table3.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

TASKS = ("1-on", "2-on", "3-on")
METRICS = ("success", "progress", "spl", "ppl")
# Table 3 of the paper (test split, percent): agent -> metric -> (1-ON, 2-ON, 3-ON)
PAPER: dict[str, dict[str, tuple[int, int, int]]] = {
    "no-map": {
        "success": (62, 24, 10),
        "progress": (62, 39, 24),
        "spl": (35, 13, 4),
        "ppl": (35, 21, 14),
    },
    "frmqn": {
        "success": (62, 29, 13),
        "progress": (62, 42, 29),
        "spl": (50, 24, 11),
        "ppl": (50, 33, 24),
    },
    "smt": {
        "success": (63, 28, 9),
        "progress": (63, 44, 22),
        "spl": (48, 26, 7),
        "ppl": (48, 36, 18),
    },
    "oracle-map": {
        "success": (94, 74, 48),
        "progress": (94, 79, 62),
        "spl": (77, 59, 38),
        "ppl": (77, 63, 49),
    },
    "oracle-map-occ": {
        "success": (66, 34, 16),
        "progress": (66, 47, 36),
        "spl": (48, 25, 12),
        "ppl": (48, 35, 27),
    },
    "oracle-map-obj": {
        "success": (94, 82, 59),
        "progress": (94, 86, 70),
        "spl": (79, 65, 42),
        "ppl": (79, 67, 50),
    },
    "oracle-ego-map": {
        "success": (83, 64, 37),
        "progress": (83, 71, 54),
        "spl": (65, 49, 25),
        "ppl": (65, 54, 36),
    },
    "ego-map": {
        "success": (69, 46, 26),
        "progress": (69, 59, 44),
        "spl": (49, 31, 18),
        "ppl": (49, 42, 30),
    },
    "proj-neural-map": {
        "success": (70, 45, 27),
        "progress": (70, 57, 46),
        "spl": (51, 30, 18),
        "ppl": (51, 39, 31),
    },
    "obj-recog-map": {
        "success": (79, 51, 22),
        "progress": (79, 62, 40),
        "spl": (56, 38, 17),
        "ppl": (56, 45, 30),
    },
}


def parse() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agents", nargs="+", default=list(PAPER), choices=list(PAPER))
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    parser.add_argument("--frames", type=int, default=40_000_000, help="per run (paper: 40M)")
    parser.add_argument("--envs", type=int, default=16, help="environments (paper: 16)")
    parser.add_argument("--image-size", type=int, default=256, help="camera side (paper: 256)")
    parser.add_argument(
        "--renderer", default="auto", choices=["tiny", "gl", "egl", "auto"], help="camera.renderer"
    )
    parser.add_argument("--device", default="auto", help="torch device of the trainer")
    parser.add_argument("--episodes", type=int, default=None, help="test episodes (all: 1000)")
    parser.add_argument("--eval-workers", type=int, default=2)
    parser.add_argument(
        "--eval-max-steps", type=int, default=None, help="step limit for quick checks only"
    )
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("runs/table3"))
    parser.add_argument("--estimate-only", action="store_true", help="measure, print, stop")
    parser.add_argument("--no-estimate", action="store_true", help="skip the speed measurement")
    parser.add_argument(
        "--no-warm-cache",
        action="store_true",
        help="do not build the navigable grids of the train and test houses first",
    )
    return parser.parse_args()


def train_args(
    options: argparse.Namespace, agent: str, task: str, out: Path, frames: int, **changes: Any
):
    from multion_agents.learned.ppo import Args

    values: dict[str, Any] = dict(
        agent=agent,
        task=task,
        frames=frames,
        envs=options.envs,
        image_size=options.image_size,
        seed=options.seed,
        out=str(out),
        device=options.device,
        env_overrides={"camera": {"renderer": options.renderer}},
        extra={"reproduce_table3": True},
    )
    values.update(changes)
    return Args(**values)


def warm_grid_cache() -> None:
    """Build (or find in the disk cache) the navigable grid of every train and test house once,
    so that neither the speed measurement nor the first training hours pay for ray casts."""
    from tqdm import tqdm

    from multion.scenes.registry import scene_ids
    from multion.sim.simulator import Simulator

    simulator = Simulator()
    try:
        for scene in tqdm(scene_ids("train") + scene_ids("test"), desc="navigable grids"):
            simulator.load_scene(scene)
    finally:
        simulator.close()


def estimate(options: argparse.Namespace) -> dict[str, float]:
    """Frames per second of two PPO updates per agent (1-ON, the run's settings); prints the
    estimated hours of one run of ``--frames``."""
    from multion_agents.learned.training_run import train

    rates: dict[str, float] = {}
    print(
        f"measuring training speed ({options.envs} envs, {options.image_size}², "
        f"renderer {options.renderer}): two PPO updates per agent"
    )
    for agent in options.agents:
        with tempfile.TemporaryDirectory(prefix="table3-estimate-") as directory:
            per_update = 128 * options.envs
            summary = train(
                train_args(
                    options,
                    agent,
                    "1-on",
                    Path(directory),
                    2 * per_update,
                    progress=False,
                    tensorboard=False,
                    checkpoint_every=10**9,
                )
            )
        rates[agent] = float(summary["fps"])  # the second update: start-up excluded
        seconds = options.frames / rates[agent]
        print(
            f"  {agent:18s} {rates[agent]:8.1f} frames/s -> {duration(seconds)} per run, "
            f"{duration(seconds * len(options.tasks))} for {len(options.tasks)} tasks"
        )
    total = sum(options.frames / r for r in rates.values()) * len(options.tasks)
    print(
        f"  all {len(rates) * len(options.tasks)} runs: {duration(total)} of training, "
        "one run at a time on this machine (evaluation not included)"
    )
    return rates


def duration(seconds: float) -> str:
    if seconds < 3600:
        return f"{seconds / 60:.1f} min"
    if seconds < 3 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"


def run_training(options: argparse.Namespace, agent: str, task: str, out: Path) -> Path:
    from multion_agents.learned.checkpoint import load_checkpoint
    from multion_agents.learned.training_run import train

    checkpoint = out / "checkpoint.pt"
    if checkpoint.is_file():
        done = load_checkpoint(checkpoint)["frames"]
        if done >= options.frames:
            print(f"{agent} {task}: trained ({done} frames), skipped")
            return checkpoint
        print(f"{agent} {task}: resuming at {done} frames")
    train(train_args(options, agent, task, out, options.frames, resume=checkpoint.is_file()))
    return checkpoint


def run_evaluation(
    options: argparse.Namespace, agent: str, task: str, checkpoint: Path, out: Path
) -> dict[str, Any]:
    from multion.config.datasets import parse_task
    from multion_agents.evaluate import EvalSettings, evaluate
    from multion_agents.report.run_summary import write_report

    metrics_path = out / "metrics.json"
    current = metrics_path.is_file() and metrics_path.stat().st_mtime >= checkpoint.stat().st_mtime
    if current:
        print(f"{agent} {task}: evaluated, skipped")
    else:
        if out.exists():  # an evaluation of an earlier checkpoint: evaluate the new one
            shutil.rmtree(out)
        settings = EvalSettings(
            agent=agent,
            num_goals=parse_task(task),
            split="test",
            episodes=options.episodes,
            seed=options.seed,
            workers=options.eval_workers,
            image_size=options.image_size,
            max_steps=options.eval_max_steps,
            checkpoint=str(checkpoint),
        )
        partial = out.with_name(out.name + ".partial")  # renamed when complete: resumable
        shutil.rmtree(partial, ignore_errors=True)
        write_report(evaluate(settings), partial, pictures=1)
        os.replace(partial, out)
    return json.loads(metrics_path.read_text())["metrics"]


def write_table(results: dict[str, dict[str, dict[str, Any]]], options: argparse.Namespace) -> Path:
    """``table3.md``: ours / paper per metric and task, percent (our 95% CI in table3.json)."""
    header = "| agent | " + " | ".join(f"{m} {t}" for m in METRICS for t in options.tasks) + " |"
    lines = [
        f"Table 3 reproduced: ours / paper, test split, percent. Budget {options.frames:,} "
        f"frames per run, {options.envs} envs, {options.image_size}² camera, "
        f"renderer {options.renderer}"
        + (f", evaluation step limit {options.eval_max_steps}" if options.eval_max_steps else "")
        + (f", {options.episodes} test episodes" if options.episodes else "")
        + ".",
        "",
        header,
        "|" + " --- |" * (1 + len(METRICS) * len(options.tasks)),
    ]
    for agent in options.agents:
        cells = []
        for metric in METRICS:
            for task in options.tasks:
                ours = results.get(agent, {}).get(task, {}).get(metric, {}).get("mean", math.nan)
                paper = PAPER[agent][metric][TASKS.index(task)]
                cells.append(f"{100 * ours:.0f} / {paper}")
        lines.append(f"| {agent} | " + " | ".join(cells) + " |")
    for path, text in (
        (options.out / "table3.md", "\n".join(lines) + "\n"),
        (
            options.out / "table3.json",
            json.dumps({"ours": results, "paper": PAPER}, indent=2) + "\n",
        ),
    ):
        temporary = path.with_name(path.name + ".tmp")
        temporary.write_text(text, encoding="utf-8")
        os.replace(temporary, path)
    return options.out / "table3.md"


def main() -> int:
    options = parse()
    options.out.mkdir(parents=True, exist_ok=True)
    if not options.no_warm_cache:
        warm_grid_cache()
    if not options.no_estimate:
        estimate(options)
    if options.estimate_only:
        return 0
    results: dict[str, dict[str, dict[str, Any]]] = {}
    for agent in options.agents:
        for task in options.tasks:
            run = options.out / agent / task
            checkpoint = run_training(options, agent, task, run)
            metrics = run_evaluation(options, agent, task, checkpoint, run / "test")
            results.setdefault(agent, {})[task] = metrics
            write_table(results, options)  # a partial table after every run
    print((options.out / "table3.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
