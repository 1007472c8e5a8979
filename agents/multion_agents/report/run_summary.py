"""Summaries of one evaluation: means with 95% confidence intervals, a table, and result files.

Confidence intervals are percentile bootstrap intervals over episodes (:mod:`.stats`). With few
episodes they are wide; that is the honest answer.

Files written to the output directory:

* ``metrics.json``: the aggregates and the run's configuration (agent, task, split, episodes,
  seed and how each episode's agent was seeded from it (``seed_scheme``), server, the agent's own settings, the ``--set`` overrides, the environment config as sent and with every default
  filled in, the dataset file's SHA-256, package versions);
* ``episodes.jsonl``: one JSON object per episode (id, scene, the server's metrics, timings, the
  actions played: what ``multion video`` replays);
* ``episode-<id>.png``: top-down pictures of the first few episodes (see :mod:`multion.sim.pictures`).
"""

from __future__ import annotations

import json
import platform
from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from multion.common.files import write_atomically
from multion.config.datasets import task_name
from multion_agents.evaluate import EpisodeRecord, EvalResult
from multion_agents.report.stats import CI_METHOD, HEADLINE, bootstrap


def summarize(records: Sequence[EpisodeRecord]) -> dict[str, Any]:
    """The aggregate numbers of a run (JSON-ready)."""
    summary: dict[str, Any] = {"episodes": len(records)}
    for key, _ in HEADLINE:
        estimate = bootstrap([float(r.metrics.get(key, 0.0)) for r in records])
        summary[key] = asdict(estimate)
    if records:
        summary["mean_steps"] = float(np.mean([r.metrics.get("steps", 0) for r in records]))
        summary["mean_collisions"] = float(
            np.mean([r.metrics.get("collisions", 0) for r in records])
        )
        summary["mean_path_length"] = float(
            np.mean([r.metrics.get("path_length", 0.0) for r in records])
        )
        summary["end_reasons"] = dict(Counter(str(r.metrics.get("end_reason")) for r in records))
        total = sum(r.total_seconds for r in records)
        summary["agent_time_fraction"] = sum(r.agent_seconds for r in records) / max(total, 1e-9)
        summary["seconds_per_episode"] = total / len(records)
    summary["ci_method"] = CI_METHOD
    return summary


def format_table(summary: dict[str, Any], title: str) -> str:
    """A plain-text table: one row per metric, in percent, with the 95% interval."""
    lines = [title, f"{'metric':<10}{'mean %':>8}   95% CI (bootstrap)"]
    for key, name in HEADLINE:
        e = summary[key]
        lines.append(
            f"{name:<10}{100 * e['mean']:>8.1f}   [{100 * e['low']:5.1f}, {100 * e['high']:5.1f}]"
        )
    lines.append(f"{'episodes':<10}{summary['episodes']:>8d}")
    if "mean_steps" in summary:
        lines.append(f"{'steps':<10}{summary['mean_steps']:>8.1f}   (mean per episode)")
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(summary["end_reasons"].items()))
        lines.append(f"{'ended by':<10}  {reasons}")
        lines.append(
            f"{'agent time':<10}{100 * summary['agent_time_fraction']:>8.1f}   "
            f"(% of episode wall time spent in act())"
        )
    return "\n".join(lines)


def title_of(result: EvalResult) -> str:
    s = result.settings
    where = "in-process" if s.in_process else s.server or "local server"
    return f"{s.agent} on {task_name(s.num_goals)} {s.split} ({where}, seed {s.seed})"


DISTRIBUTIONS = {
    "multion": "multion-pybullet",
    "multion-client": "multion-client",
    "numpy": "numpy",
    "pybullet": "pybullet",
}


def versions() -> dict[str, str]:
    found = {"python": platform.python_version()}
    # key → distribution (the multion distribution is called multion-pybullet on the index)
    for key, distribution in DISTRIBUTIONS.items():
        try:
            found[key] = metadata.version(distribution)
        except metadata.PackageNotFoundError:
            found[key] = "not installed"
    return found


def write_report(result: EvalResult, out: Path, pictures: int = 3) -> list[Path]:
    """Write metrics.json, episodes.jsonl and up to ``pictures`` PNGs into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    s = result.settings
    run = {
        "agent": s.agent,
        "task": task_name(s.num_goals),
        "split": s.split,
        "episodes": len(result.records),
        "episodes_requested": s.episodes,
        "seed": s.seed,
        "seed_scheme": result.seed_scheme,  # absent before issue 53: "index"
        "workers": s.workers,
        "dataset": s.dataset,
        "checkpoint": s.checkpoint,
        "deterministic": s.deterministic,
        "agent_settings": result.agent_settings,
        "server": result.server,
        "max_steps": s.max_steps,
        "image_size": s.image_size,
        "env_overrides": s.env_overrides,
        "env_config": result.config,
        "resolved_config": result.resolved_config,
        "dataset_sha256": result.dataset_sha256,
        "versions": versions(),
        "seconds": round(result.seconds, 2),
    }
    # episodes first: a metrics.json is only ever next to the complete episodes it summarizes
    episodes_path = out / "episodes.jsonl"
    lines = "".join(json.dumps(record.to_json()) + "\n" for record in result.records)
    write_atomically(episodes_path, lines)
    metrics_path = out / "metrics.json"
    payload = {"run": run, "metrics": summarize(result.records)}
    write_atomically(metrics_path, json.dumps(payload, indent=2) + "\n")
    written = [metrics_path, episodes_path]
    if pictures > 0:
        from multion.sim.pictures import episode_picture
        from multion.sim.simulator import Simulator

        by_id = {e.episode_id: e for e in result.episodes}
        simulator = Simulator()  # one for all pictures: scenes and grids are reused
        try:
            for record in result.records[:pictures]:
                episode = by_id[record.episode_id]
                image = episode_picture(episode, record.path, record.metrics, simulator)
                path = out / f"episode-{record.episode_id}.png"
                image.save(path)
                written.append(path)
        finally:
            simulator.close()
    return written
