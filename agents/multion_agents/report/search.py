"""How much ground each run's search covered: the task's ``cells_visited`` (2.5 m cells of the
start frame an episode stood in), per episode and in the episodes that ran to the step limit.
It tells an agent that walks far and misses its goal from one that stays near its start: what
issue 51 measured of the agents that must see. Runs evaluated before the task measured it are
left out, and a note says so.
"""

from __future__ import annotations

from collections.abc import Sequence

from multion.config.datasets import task_name
from multion_agents.report.paper import PaperResults
from multion_agents.report.runs import Run
from multion_agents.report.stats import bootstrap
from multion_agents.report.tables import Table, display_order

MEASURE = "cells_visited"


def search_coverage(
    runs: Sequence[Run], labels: Sequence[str], paper: PaperResults
) -> Table | None:
    """Mean ``cells_visited`` per episode (95 % bootstrap interval), over all of a run's
    episodes and over those that ended at the step limit; None when no run has it."""
    measured = [i for i, run in enumerate(runs) if all(MEASURE in e.metrics for e in run.episodes)]
    if not measured:
        return None
    table = Table(
        "search",
        "Ground searched: 2.5 m cells entered per episode",
        ["agent", "task", "every episode", "episodes at the step limit"],
    )
    for i in display_order(runs, labels, paper):
        if i not in measured:
            continue
        run = runs[i]
        cells = [float(e.metrics[MEASURE]) for e in run.episodes]
        limit = [
            float(e.metrics[MEASURE])
            for e in run.episodes
            if e.metrics.get("end_reason") == "max_steps"
        ]
        every, at_limit = bootstrap(cells), bootstrap(limit)
        table.rows.append(
            [
                labels[i],
                task_name(run.num_goals),
                f"{every.mean:.1f} [{every.low:.1f}, {every.high:.1f}]",
                f"{at_limit.mean:.1f} ({len(limit)})" if limit else "– (0)",
            ]
        )
        table.records.append(
            {
                "run": run.name,
                "agent": labels[i],
                "task": task_name(run.num_goals),
                "cells": round(every.mean, 3),
                "cells_low": round(every.low, 3),
                "cells_high": round(every.high, 3),
                "episodes_at_step_limit": len(limit),
                "cells_at_step_limit": round(at_limit.mean, 3) if limit else None,
            }
        )
    table.notes.append(
        "The task's cells_visited: cells of a 2.5 m grid in the episode's start frame (the "
        "start at a cell's centre) that the agent stood in, the start's included; beyond the "
        "paper (Ye et al., ICCV 2021's coverage grid)."
    )
    table.note_left_out(
        [labels[i] for i in range(len(runs)) if i not in measured],
        "evaluated before the task measured cells_visited",
    )
    return table
