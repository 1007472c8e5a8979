"""How each run searched, from the task's measures (beyond the paper; issue 51 measured the
agents that must see with them). Runs evaluated before the task measured them are left out,
and a note says so.

* :func:`search_coverage`: ``cells_visited`` (2.5 m cells of the start frame an episode stood
  in), per episode and in the episodes that ran to the step limit, with how far those walked
  (``path_length``). It tells an agent that walks far and misses its goal from one that stays
  near its start, and one that loops (far walked, few cells) from one stuck against a wall.
* :func:`search_or_stop`: ``closest_to_goal`` splits the lost episodes into those that stood
  within reach of the goal they were lost on (FOUND was not called there: a stopping failure)
  and those that never came that near (a search failure).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from multion.config.datasets import task_name
from multion_agents.report.paper import PaperResults
from multion_agents.report.runs import EpisodeResult, Run
from multion_agents.report.stats import NAN, Estimate, bootstrap, paired_difference
from multion_agents.report.tables import Table, display_order, estimate_record, signed

MEASURE = "cells_visited"
CLOSEST = "closest_to_goal"
SEEN = "current_goal_seen"
# a step-limited episode that walked less than this is stuck: 40 forward steps of 0.25 m in
# 2,500 steps (the defaults of agent.forward_step and task.max_steps, the reference's values:
# multion.config.reference)
STUCK_METRES = 10.0


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
        [
            "agent",
            "task",
            "every episode",
            "episodes at the step limit",
            "their m walked, median",
            f"of them, stuck (under {STUCK_METRES:.0f} m)",
        ],
    )
    for i in display_order(runs, labels, paper):
        if i not in measured:
            continue
        run = runs[i]
        cells = [float(e.metrics[MEASURE]) for e in run.episodes]
        limited = [e for e in run.episodes if e.metrics.get("end_reason") == "max_steps"]
        limit = [float(e.metrics[MEASURE]) for e in limited]
        walked = [float(e.metrics["path_length"]) for e in limited if "path_length" in e.metrics]
        stuck = sum(metres < STUCK_METRES for metres in walked)
        every, at_limit = bootstrap(cells), bootstrap(limit)
        median_walked = float(np.median(walked)) if walked else None
        table.rows.append(
            [
                labels[i],
                task_name(run.num_goals),
                f"{every.mean:.1f} [{every.low:.1f}, {every.high:.1f}]",
                f"{at_limit.mean:.1f} ({len(limit)})" if limit else "– (0)",
                "–" if median_walked is None else f"{median_walked:.0f}",
                "–" if not walked else str(stuck),
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
                "walked_at_step_limit_median": (
                    None if median_walked is None else round(median_walked, 3)
                ),
                "stuck_at_step_limit": stuck if walked else None,
            }
        )
    table.notes.append(
        "The task's cells_visited: cells of a 2.5 m grid in the episode's start frame (the "
        "start at a cell's centre) that the agent stood in, the start's included; beyond the "
        "paper (Ye et al., ICCV 2021's coverage grid). Walked: the task's path_length in the "
        f"episodes at the step limit; stuck: under {STUCK_METRES:.0f} m in all its steps (40 "
        "forward steps of 0.25 m); many metres over few cells is a loop."
    )
    table.note_left_out(
        [labels[i] for i in range(len(runs)) if i not in measured],
        "evaluated before the task measured cells_visited",
    )
    return table


def came_within_reach(run: Run, episode: EpisodeResult) -> bool:
    """Whether ``episode`` won or stood within ``run``'s success distance of the goal it ended
    on (the task's ``closest_to_goal``)."""
    metrics = episode.metrics
    return metrics.get("success", 0.0) >= 1.0 or float(metrics[CLOSEST]) <= run.success_distance


def _measures(run: Run, name: str) -> bool:
    return all(name in e.metrics for e in run.episodes)


def _share(estimate: Estimate) -> str:
    return f"{100 * estimate.mean:.0f} [{100 * estimate.low:.0f}, {100 * estimate.high:.0f}]"


def search_or_stop(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table | None:
    """Per run, the shares of episodes that came within reach of the goal they ended on and
    that saw it (95 % bootstrap intervals), and the lost episodes split by whether they came
    within reach, and if not, whether they saw the goal; None when no run measured
    ``closest_to_goal``."""
    measured = [i for i, run in enumerate(runs) if _measures(run, CLOSEST)]
    if not measured:
        return None
    table = Table(
        "search-or-stop",
        "Search or stop: episodes within reach of their goal, and where the lost ones were lost",
        ["agent", "task", "came within reach %", "saw the goal %", "won", "lost within reach",
         "lost, never within reach", "of them, saw the goal", "their closest approach, median m"],
    )  # fmt: skip
    for i in display_order(runs, labels, paper):
        if i not in measured:
            continue
        run = runs[i]
        won = [e.metrics.get("success", 0.0) >= 1.0 for e in run.episodes]
        within = [came_within_reach(run, e) for e in run.episodes]
        lost_far = [not w for w in within]
        far = [float(e.metrics[CLOSEST]) for e, lost in zip(run.episodes, lost_far, strict=True)
               if lost]  # fmt: skip
        median = float(np.median(far)) if far else None
        seen_flags = [bool(e.metrics[SEEN]) for e in run.episodes] if _measures(run, SEEN) else None
        seen_far = (
            None
            if seen_flags is None
            else sum(seen and lost for seen, lost in zip(seen_flags, lost_far, strict=True))
        )
        came = bootstrap([float(w) for w in within])
        table.rows.append(
            [
                labels[i],
                task_name(run.num_goals),
                _share(came),
                _share(bootstrap([float(s) for s in seen_flags]))
                if seen_flags is not None
                else "–",
                str(sum(won)),
                str(sum(within) - sum(won)),
                str(len(far)),
                str(seen_far) if seen_far is not None else "–",
                f"{median:.1f}" if median is not None else "–",
            ]
        )
        table.records.append(
            {
                "run": run.name,
                "agent": labels[i],
                "task": task_name(run.num_goals),
                "episodes": run.count,
                "success_distance": run.success_distance,
                "within_reach": round(came.mean, 4),
                "within_reach_low": round(came.low, 4),
                "within_reach_high": round(came.high, 4),
                "saw_goal": None if seen_flags is None else sum(seen_flags),
                "won": sum(won),
                "lost_within_reach": sum(within) - sum(won),
                "lost_never_within_reach": len(far),
                "lost_never_within_reach_seen": seen_far,
                "closest_approach_median": round(median, 3) if median is not None else None,
            }
        )
    table.notes.append(
        "Within reach: the task's closest_to_goal, the shortest geodesic distance to the goal "
        "an episode ended on since that goal became current, at most task.success_distance. A "
        "won episode counts as within reach. Saw the goal: the task's current_goal_seen, the "
        "goal in the field of view within maps.view_distance with a clear line on the grid "
        "('–' for runs evaluated before the task measured it; `multion rescore` adds it). Lost "
        "within reach: FOUND was not called there (a stopping failure); lost, never within "
        "reach: the search did not get there (a search failure), with how many of them saw "
        "the goal and the median of how near they came. Beyond the paper."
    )
    table.note_left_out(
        [labels[i] for i in range(len(runs)) if i not in measured],
        "evaluated before the task measured closest_to_goal",
    )
    return table


def search_pairs(
    runs: Sequence[Run], labels: Sequence[str], pairs: Sequence[tuple[int, int]]
) -> Table | None:
    """For each pair asked for (``--pair``) whose runs both measured ``closest_to_goal``: A − B
    of the shares that came within reach and that saw the goal, on the episodes both played
    (95 % paired bootstrap intervals); None when there is no such pair."""
    table = Table(
        "search-pairs",
        "Search or stop for the pairs asked for: A − B on the episodes both played "
        "(percentage points)",
        ["A", "B", "task", "common episodes", "Δ came within reach", "Δ saw the goal"],
    )
    for i, j in pairs:
        a, b = runs[i], runs[j]
        if not (_measures(a, CLOSEST) and _measures(b, CLOSEST)):
            continue
        in_b = {e.episode_id: e for e in b.episodes}
        common = [(e, in_b[e.episode_id]) for e in a.episodes if e.episode_id in in_b]
        if not common:
            continue
        reach = paired_difference(
            [float(came_within_reach(a, x)) for x, _ in common],
            [float(came_within_reach(b, y)) for _, y in common],
        )
        seen = (
            paired_difference(
                [float(x.metrics[SEEN]) for x, _ in common],
                [float(y.metrics[SEEN]) for _, y in common],
            )
            if _measures(a, SEEN) and _measures(b, SEEN)
            else NAN
        )
        table.rows.append(
            [labels[i], labels[j], task_name(a.num_goals), str(len(common)), signed(reach),
             signed(seen)]
        )  # fmt: skip
        table.records.append(
            {
                "a": labels[i],
                "b": labels[j],
                "run_a": a.name,
                "run_b": b.name,
                "task": task_name(a.num_goals),
                "common_episodes": len(common),
                **estimate_record(reach, "diff_within_reach"),
                **(
                    estimate_record(seen, "diff_saw_goal")
                    if seen is not NAN
                    else dict.fromkeys(("diff_saw_goal", "diff_saw_goal_low", "diff_saw_goal_high"))
                ),
            }
        )
    if not table.rows:
        return None
    table.notes.append(
        'As in "Search or stop": came within reach (a won episode counts) and saw the goal, '
        "each episode 1 or 0; each cell the mean of A − B with a 95% paired bootstrap interval; "
        "**bold**: the interval excludes 0."
    )
    return table
