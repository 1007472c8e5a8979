"""How each run searched, from the task's measures (beyond the paper; issue 51 measured the
agents that must see with them). Runs evaluated before the task measured them are left out,
and a note says so.

* :func:`search_coverage`: ``cells_visited`` (2.5 m cells of the start frame an episode stood
  in), per episode and in the episodes that ran to the step limit. It tells an agent that walks
  far and misses its goal from one that stays near its start.
* :func:`search_or_stop`: ``closest_to_goal`` splits the lost episodes into those that stood
  within reach of the goal they were lost on (FOUND was not called there: a stopping failure)
  and those that never came that near (a search failure).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from multion.config.datasets import task_name
from multion_agents.report.paper import PaperResults
from multion_agents.report.runs import Run
from multion_agents.report.stats import bootstrap
from multion_agents.report.tables import Table, display_order

MEASURE = "cells_visited"
CLOSEST = "closest_to_goal"
SEEN = "current_goal_seen"


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


def search_or_stop(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table | None:
    """Per run, the share of episodes that came within reach of the goal they ended on (95 %
    bootstrap interval), and the lost episodes split by whether they did; None when no run
    measured ``closest_to_goal``."""
    measured = [i for i, run in enumerate(runs) if all(CLOSEST in e.metrics for e in run.episodes)]
    if not measured:
        return None
    table = Table(
        "search-or-stop",
        "Search or stop: episodes within reach of their goal, and where the lost ones were lost",
        ["agent", "task", "came within reach %", "won", "lost within reach",
         "lost, never within reach", "of them, saw the goal", "their closest approach, median m"],
    )  # fmt: skip
    for i in display_order(runs, labels, paper):
        if i not in measured:
            continue
        run = runs[i]
        reach = run.success_distance
        won = [e.metrics.get("success", 0.0) >= 1.0 for e in run.episodes]
        closest = np.array([float(e.metrics[CLOSEST]) for e in run.episodes])
        within = closest <= reach
        came = bootstrap([float(w or x) for w, x in zip(won, within, strict=True)])
        lost_near = sum(not w and x for w, x in zip(won, within, strict=True))
        lost_far = [not w and not x for w, x in zip(won, within, strict=True)]
        far = [float(c) for c, lost in zip(closest, lost_far, strict=True) if lost]
        median = float(np.median(far)) if far else None
        seen = (
            sum(bool(e.metrics[SEEN]) for e, lost in zip(run.episodes, lost_far, strict=True)
                if lost)
            if all(SEEN in e.metrics for e in run.episodes)
            else None
        )  # fmt: skip
        table.rows.append(
            [
                labels[i],
                task_name(run.num_goals),
                f"{100 * came.mean:.0f} [{100 * came.low:.0f}, {100 * came.high:.0f}]",
                str(sum(won)),
                str(lost_near),
                str(len(far)),
                str(seen) if seen is not None else "–",
                f"{median:.1f}" if median is not None else "–",
            ]
        )
        table.records.append(
            {
                "run": run.name,
                "agent": labels[i],
                "task": task_name(run.num_goals),
                "episodes": run.count,
                "success_distance": reach,
                "within_reach": round(came.mean, 4),
                "within_reach_low": round(came.low, 4),
                "within_reach_high": round(came.high, 4),
                "won": sum(won),
                "lost_within_reach": lost_near,
                "lost_never_within_reach": len(far),
                "lost_never_within_reach_seen": seen,
                "closest_approach_median": round(median, 3) if median is not None else None,
            }
        )
    table.notes.append(
        "Within reach: the task's closest_to_goal, the shortest geodesic distance to the goal "
        "an episode ended on since that goal became current, at most task.success_distance. A "
        "won episode counts as within reach. Lost within reach: FOUND was not called there (a "
        "stopping failure); lost, never within reach: the search did not get there (a search "
        "failure), with the median of how near it came, and how many of them had the goal in "
        "view (the task's current_goal_seen: in the field of view within maps.view_distance, "
        "a clear line on the grid; '–' for runs evaluated before it, which `multion rescore` "
        "adds it to). Beyond the paper."
    )
    table.note_left_out(
        [labels[i] for i in range(len(runs)) if i not in measured],
        "evaluated before the task measured closest_to_goal",
    )
    return table
