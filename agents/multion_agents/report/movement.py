"""How each run moved: the shares of its actions, the forward steps the simulator refused, and
the metres walked per step, from the actions ``episodes.jsonl`` keeps and the task's
``collisions`` and ``path_length``. Beside the ground searched (:mod:`.search`) it tells a
search that walks into walls or turns in circles from one that goes places: what issue 51
measured of the agents that must see. Runs whose episodes do not keep their actions are left
out, and a note says so.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

from multion.config.datasets import task_name
from multion_agents.report.paper import PaperResults
from multion_agents.report.runs import Run
from multion_agents.report.tables import Table, display_order
from multion_client.constants import Action

ACTION_NAMES = {
    Action.FOUND: "found",
    Action.MOVE_FORWARD: "forward",
    Action.TURN_LEFT: "left",
    Action.TURN_RIGHT: "right",
}
"""Each action's name in the table's records (``forward_share``, ...); ``episodes.jsonl``
writes an action as its value's digit (``evaluate.actions_text``)."""


def movement(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table | None:
    """Per run, over all its steps: each action's share, the share of forward steps refused (a
    step that would leave the navigable area is refused and counts as a collision) and the
    metres walked per step; None when no run kept its actions."""
    kept = [i for i, run in enumerate(runs) if all(e.actions for e in run.episodes)]
    if not kept:
        return None
    table = Table(
        "movement",
        "How it moves: shares of its steps (%) and metres per step",
        [
            "agent",
            "task",
            "forward",
            "left",
            "right",
            "FOUND",
            "forward refused",
            "m per step",
            "m per cell entered",
        ],
    )
    for i in display_order(runs, labels, paper):
        if i not in kept:
            continue
        run = runs[i]
        digits = Counter("".join(e.actions for e in run.episodes))
        counts = {name: digits[str(int(action))] for action, name in ACTION_NAMES.items()}
        steps = sum(counts.values())
        collisions = sum(float(e.metrics.get("collisions", 0)) for e in run.episodes)
        metres = sum(float(e.metrics.get("path_length", 0)) for e in run.episodes)
        shares = {name: 100 * count / steps for name, count in counts.items()}
        refused = 100 * collisions / counts["forward"] if counts["forward"] else 0.0
        per_step = metres / steps
        cells = [e.metrics.get("cells_visited") for e in run.episodes]
        counted = [float(c) for c in cells if isinstance(c, (int, float)) and c > 0]
        per_cell = metres / sum(counted) if len(counted) == len(cells) else None
        table.rows.append(
            [labels[i], task_name(run.num_goals)]
            + [f"{shares[name]:.1f}" for name in ("forward", "left", "right", "found")]
            + [f"{refused:.1f}", f"{per_step:.3f}", "–" if per_cell is None else f"{per_cell:.1f}"]
        )
        table.records.append(
            {
                "run": run.name,
                "agent": labels[i],
                "task": task_name(run.num_goals),
                "steps": steps,
                **{f"{name}_share": round(shares[name], 3) for name in ACTION_NAMES.values()},
                "forward_refused_share": round(refused, 3),
                "metres_per_step": round(per_step, 4),
                "metres_per_cell": None if per_cell is None else round(per_cell, 3),
            }
        )
    table.notes.append(
        "Over all of a run's steps. A forward step that would leave the navigable area is "
        "refused (the agent stays, the task counts a collision): 'forward refused' is "
        "collisions over forward steps. Uniform random movement turns on two steps in three; "
        "left and right far apart mean turning in circles. 'm per cell entered': metres walked "
        "over the 2.5 m cells entered (cells_visited; '–' for runs evaluated before it), high "
        "for a search that loops over ground already covered. Beyond the paper."
    )
    table.note_left_out(
        [labels[i] for i in range(len(runs)) if i not in kept],
        "episodes.jsonl without the actions taken",
    )
    return table
