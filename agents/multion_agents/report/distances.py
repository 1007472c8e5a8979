"""Success by how far the goals are: each run's episodes in four quarters of the shortest path
from the start through its goals in order (the dataset's ``geodesic_distances``, summed), with
the quarters' edges per task in metres. It tells an agent that finds near goals but not far ones
(too little search) from one that misses near ones too (it does not call FOUND where it should):
what issue 51 needed to know of the agents that must see.

A run's distances come from the packaged dataset it was evaluated on, matched by checksum; a run
on any other dataset is left out, and a note says so.
"""

from __future__ import annotations

import functools
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from multion.config.datasets import DATA_DIR, dataset_sha256, load_dataset, task_name
from multion_agents.report.paper import PaperResults
from multion_agents.report.runs import Run, dataset_label
from multion_agents.report.tables import Table, display_order

QUARTERS = ("nearest quarter", "second", "third", "farthest quarter")


def shortest_paths(run: Run) -> dict[str, float] | None:
    """Episode id → metres from the start through every goal, for a run on a packaged
    dataset; None for a run on another one."""
    for path in sorted(DATA_DIR.glob(f"*/{run.split}.json.gz")):
        if _checksum(path) == run.dataset:
            return _paths(path)
    return None


@functools.cache
def _checksum(path: Path) -> str:
    return dataset_label(dataset_sha256(path))


@functools.cache
def _paths(path: Path) -> dict[str, float]:
    return {e.episode_id: float(sum(e.geodesic_distances)) for e in load_dataset(path)}


def by_distance(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table | None:
    """Success (%) in each quarter of the episodes' shortest paths, per run; the quarters of
    a task are cut from all of its runs' episodes together."""
    known = {i: shortest_paths(run) for i, run in enumerate(runs)}
    distances: dict[int, dict[str, float]] = defaultdict(dict)  # task's goals → id → metres
    for i, paths in known.items():
        if paths is not None:
            distances[runs[i].num_goals].update(
                {
                    e.episode_id: paths[e.episode_id]
                    for e in runs[i].episodes
                    if e.episode_id in paths
                }
            )
    if not distances:
        return None
    edges = {
        goals: np.round(np.quantile(list(metres.values()), [0.25, 0.5, 0.75]), 1)
        for goals, metres in distances.items()
    }
    table = Table(
        "by-distance",
        "Success by the goals' distance: quarters of the shortest path (%)",
        ["agent", "task", *(f"{name} (episodes)" for name in QUARTERS)],
    )
    for i in display_order(runs, labels, paper):
        paths, run = known[i], runs[i]
        if paths is None:
            continue
        cuts = edges[run.num_goals]
        cells = []
        for quarter in range(len(QUARTERS)):
            low = cuts[quarter - 1] if quarter else 0.0
            high = cuts[quarter] if quarter < len(cuts) else np.inf
            chosen = [
                e
                for e in run.episodes
                if e.episode_id in paths and low <= paths[e.episode_id] < high
            ]
            won = sum(float(e.metrics.get("success", 0.0)) for e in chosen)
            share = 100.0 * won / len(chosen) if chosen else float("nan")
            cells.append("–" if not chosen else f"{share:.0f} ({len(chosen)})")
            table.records.append(
                {
                    "run": run.name,
                    "agent": labels[i],
                    "task": task_name(run.num_goals),
                    "quarter": quarter + 1,
                    "from_m": float(low),
                    "to_m": float(high),
                    "episodes": len(chosen),
                    "success": round(share, 2),
                }
            )
        table.rows.append([labels[i], task_name(run.num_goals), *cells])
    for goals, cuts in sorted(edges.items()):
        table.notes.append(
            f"{task_name(goals)}: the quarters split at "
            + ", ".join(f"{cut:g}" for cut in cuts)
            + " m of shortest path (start through every goal in order), over the "
            f"{len(distances[goals])} episodes its runs played."
        )
    table.note_left_out(
        [labels[i] for i, paths in known.items() if paths is None],
        "not on a packaged dataset, so no distances",
    )
    return table
