"""Tables of runs that differ in one condition only: the found budget (the supplement's
tab:found-budget), the goal set (its tab:color_vs_shape: NoMap with coloured cylinders
against NoMap with red shapes) and the camera (an agent trained and evaluated at another image
size or with another renderer: issue 44's 128² runs against the 36² ones)."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from typing import Any

from multion.config.datasets import task_name
from multion_agents.report.paper import PaperResults
from multion_agents.report.runs import Run
from multion_agents.report.stats import CI_METHOD, HEADLINE, bootstrap
from multion_agents.report.tables import (
    Table,
    display_order,
    estimate_record,
    headline_cells,
    noted_pair,
    percent,
    signed,
    task_label,
)
from multion_client.constants import GOAL_SETS

BUDGET_METRICS = ("progress", "success", "ppl", "spl")  # the paper's column order


def found_budget(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table | None:
    """Runs of one agent and task that differ only in ``task.found_budget``, side by side."""
    groups: dict[tuple[str, ...], list[int]] = defaultdict(list)
    for i in display_order(runs, labels, paper):
        run = runs[i]
        conditions = run.conditions()
        group = (
            run.agent_label,
            str(run.num_goals),
            *(v for k, v in conditions.items() if k != "found budget"),
        )
        groups[group].append(i)
    names = dict(HEADLINE)
    table = Table(
        "found-budget",
        "Found budget: wrong FOUNDs allowed before one ends the episode (%)",
        [
            "agent",
            "task",
            "found budget",
            "episodes",
            *(f"{names[key]} %" for key in BUDGET_METRICS),
            "paper P / S / PPL / SPL",
        ],
    )
    for members in groups.values():
        if len({runs[i].found_budget for i in members}) < 2:
            continue
        for i in sorted(members, key=lambda i: runs[i].found_budget):
            run = runs[i]
            estimates = {key: bootstrap(run.values(key)) for key in BUDGET_METRICS}
            theirs = paper.budget_row(run.agent, run.num_goals, run.found_budget)
            table.rows.append(
                [
                    run.agent_label,
                    task_label(run),
                    str(run.found_budget),
                    str(run.count),
                    *(percent(estimates[key]) for key in BUDGET_METRICS),
                    " / ".join(f"{theirs[key]:.0f}" for key in BUDGET_METRICS) if theirs else "",
                ]
            )
            record: dict[str, Any] = {
                "agent": labels[i],
                "task": task_name(run.num_goals),
                "run": run.name,
                "found_budget": run.found_budget,
                "episodes": run.count,
            }
            for key in BUDGET_METRICS:
                record.update(estimate_record(estimates[key], key))
                record[f"paper_{key}"] = theirs[key] if theirs else None
            table.records.append(record)
    if not table.rows:
        return None
    table.notes.append(
        "Rows of one agent and task whose runs differ only in `task.found_budget` "
        f"(`multion eval --set task.found_budget=N`). Intervals: {CI_METHOD}."
    )
    if any(row[-1] for row in table.rows):
        table.notes.append(f"Paper columns: {paper.found_budget['source']}. {paper.setting}")
    return table


def goal_sets(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table | None:
    """Runs of one agent and task that differ only in ``task.goal_set`` (each its own checkpoint
    when learned), side by side, then each pair's paired difference on the episodes both played
    (the goal sets share their episodes: only what the goals look like changes)."""
    groups: dict[tuple[str, ...], list[int]] = defaultdict(list)
    for i in display_order(runs, labels, paper):
        run = runs[i]
        others = tuple(v for k, v in run.conditions().items() if k != "goal set")
        group = (run.agent, str(run.num_goals), *others)
        groups[group].append(i)
    names = [name for _, name in HEADLINE]
    table = Table(
        "goal-sets",
        "Goal sets: the paper's coloured cylinders against other goals (%)",
        [
            "agent",
            "task",
            "goal set",
            "episodes",
            *(f"{n} %" for n in names),
            "paper S / P / SPL / PPL",
        ],
    )
    order = list(GOAL_SETS)
    for members in groups.values():
        if len({runs[i].goal_set for i in members}) < 2:
            continue
        members = sorted(members, key=lambda i: order.index(runs[i].goal_set))
        for i in members:
            run = runs[i]
            theirs = paper.goal_set_row(run.agent, run.num_goals, run.goal_set)
            cells, fields = headline_cells(run, theirs)
            table.rows.append(
                [
                    labels[i],
                    task_label(run),
                    run.goal_set,
                    str(run.count),
                    *cells,
                    " / ".join(f"{theirs[key]:.0f}" for key, _ in HEADLINE) if theirs else "",
                ]
            )
            record: dict[str, Any] = {
                "agent": labels[i],
                "task": task_name(run.num_goals),
                "goal_set": run.goal_set,
                "run": run.name,
                "episodes": run.count,
                **fields,
            }
            table.records.append(record)
        for position, i in enumerate(members):
            for j in members[position + 1 :]:
                later, earlier = runs[j], runs[i]
                if later.goal_set != earlier.goal_set:
                    name = f"{later.goal_set} − {earlier.goal_set} (paired)"
                    paper_cell = _paper_goal_set_difference(paper, later, earlier)
                    _difference_row(table, later, earlier, "goal_set", name, paper_cell)
    if not table.rows:
        return None
    table.notes.append(
        "Rows of one agent and task whose runs differ only in `task.goal_set` (a checkpoint "
        "trained with `--set task.goal_set=shapes` plays in that set). A row `B − A (paired)` "
        "is the mean difference over the episodes both played with a 95% paired bootstrap "
        f"interval; **bold**: it excludes 0. Other intervals: {CI_METHOD}."
    )
    if any(row[-1] for row in table.rows):
        table.notes.append(
            f"Paper columns: {paper.colour_vs_shape['source']}. {paper.setting} Not comparable "
            "in absolute terms: other buildings, other simulator, test set."
        )
    return table


def cameras(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table | None:
    """Runs of one agent and task that differ only in the camera's size or renderer (a learned
    agent's checkpoints from training runs of one name), side by side, then each larger
    image's paired difference from the smaller on the episodes both played."""
    groups: dict[tuple[str, ...], list[int]] = defaultdict(list)
    for i in display_order(runs, labels, paper):
        run = runs[i]
        # one training run's checkpoint name at each size, less the camera it is named for:
        # another recipe (pretraining) is another agent here
        group = (run.label_besides_camera, str(run.num_goals),
                 *run.conditions_besides_camera().values())  # fmt: skip
        groups[group].append(i)
    names = [name for _, name in HEADLINE]
    table = Table(
        "cameras",
        "Image size: one agent trained and evaluated with another camera (%)",
        ["agent", "task", "camera", "episodes", *(f"{n} %" for n in names)],
    )
    for members in groups.values():
        if len({runs[i].camera for i in members}) < 2:
            continue
        members = sorted(members, key=lambda i: (runs[i].camera_width, runs[i].renderer))
        for i in members:
            run = runs[i]
            cells, fields = headline_cells(run, None)
            table.rows.append([labels[i], task_label(run), run.camera, str(run.count), *cells])
            record: dict[str, Any] = {"agent": labels[i], "task": task_name(run.num_goals)}
            record.update(camera=run.camera, run=run.name, episodes=run.count, **fields)
            table.records.append(record)
        for position, i in enumerate(members):
            for j in members[position + 1 :]:
                larger, smaller = runs[j], runs[i]
                if larger.camera != smaller.camera:
                    name = f"{larger.camera} − {smaller.camera} (paired)"
                    _difference_row(table, larger, smaller, "camera", name)
    if not table.rows:
        return None
    table.notes.append(
        "Rows of one agent and task whose runs differ only in the camera (`--image-size`, "
        "`--set camera.renderer=...`; a learned agent is trained at its size). A row "
        "`A − B (paired)` is the mean difference over the episodes both played with a 95% "
        f"paired bootstrap interval; **bold**: it excludes 0. Other intervals: {CI_METHOD}."
    )
    return table


def _paper_goal_set_difference(paper: PaperResults, later: Run, earlier: Run) -> str:
    """The paper's ``later − earlier`` of the two goal sets' rows, '' where it lacks one."""
    theirs_later = paper.goal_set_row(later.agent, later.num_goals, later.goal_set)
    theirs_earlier = paper.goal_set_row(earlier.agent, earlier.num_goals, earlier.goal_set)
    if not (theirs_later and theirs_earlier):
        return ""
    return " / ".join(f"{theirs_later[key] - theirs_earlier[key]:+.0f}" for key, _ in HEADLINE)


def _difference_row(
    table: Table, later: Run, earlier: Run, column: str, name: str, *after: str
) -> None:
    """The row ``name`` of ``later − earlier`` on their common episodes (95% paired bootstrap
    intervals), its record naming the pair under ``column``, with the cells ``after`` last."""
    compared = noted_pair(table, later, earlier)
    if compared is None:
        return
    common, differences, _ = compared
    cells = [signed(differences[key]) for key, _ in HEADLINE]
    table.rows.append(["", task_label(later), name, str(common), *cells, *after])
    record: dict[str, Any] = {"agent": later.agent, "task": task_name(later.num_goals)}
    record.update({column: name, "run": f"{later.name} − {earlier.name}", "episodes": common})
    for key, _ in HEADLINE:
        record.update(estimate_record(differences[key], f"diff_{key}"))
    table.records.append(record)
