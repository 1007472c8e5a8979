"""The report's tables, computed from runs: Table 3, seen / not seen, paired, the run list (the
tables over one varied condition are in :mod:`multion_agents.report.variants`).

Each builder returns a :class:`Table`: Markdown cells for reading, plain records (numbers in
percent) for the CSV file beside it, and notes. Runs are never merged: two runs that differ in
their conditions (split, dataset, found budget, other settings) get rows of their own, labelled
by what differs, and a note says so.
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from multion.config.datasets import task_name
from multion.task import measures
from multion_agents.report.paper import PaperResults
from multion_agents.report.runs import Run, seeding_difference
from multion_agents.report.stats import (
    CI_METHOD,
    HEADLINE,
    Estimate,
    bootstrap,
    independent_difference,
    paired_difference,
)
from multion_client.constants import DEFAULT_GOAL_SET


@dataclass
class Table:
    name: str
    """File stem of the CSV (``table3`` → ``table3.csv``)."""
    title: str
    header: list[str]
    rows: list[list[str]] = field(default_factory=list)
    records: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def note_left_out(self, labels: Sequence[str], why: str) -> None:
        """A note naming the runs the table leaves out and why; none when it leaves none out."""
        if labels:
            self.notes.append(f"Left out ({why}): {', '.join(labels)}.")


# ---------------------------------------------------------------------- labels and order
def run_labels(runs: Sequence[Run]) -> list[str]:
    """A row label per run: the agent, plus each condition in which the run differs from most
    runs (e.g. ``random (found budget 3)``), plus the directory name if still not unique, with
    as many of its parents as it takes (``central/oracle-map``, ``central-x/oracle-map``)."""
    usual = _usual_conditions(runs)
    labels = []
    for run in runs:
        differing = [
            value if key == "settings" else f"{key} {value}"
            for key, value in run.conditions().items()
            if value != usual[run.num_goals][key]
        ]
        labels.append(run.agent_label + (f" ({'; '.join(differing)})" if differing else ""))
    clashes = Counter((label, run.num_goals) for label, run in zip(labels, runs, strict=True))
    return [
        f"{label} [{_directory(run, runs)}]" if clashes[(label, run.num_goals)] > 1 else label
        for label, run in zip(labels, runs, strict=True)
    ]


def _directory(run: Run, runs: Sequence[Run]) -> str:
    """The run's directory name, with its parents until no other run's ends the same way."""
    parts = run.path.parts
    for depth in range(1, len(parts) + 1):
        tail = parts[-depth:]
        if not any(other.path.parts[-depth:] == tail for other in runs if other is not run):
            break
    return "/".join(tail)


def _usual_conditions(runs: Sequence[Run]) -> dict[int, dict[str, str]]:
    """Per m, the most common value of each condition (the dataset file differs with m)."""
    usual: dict[int, dict[str, str]] = {}
    for m in {run.num_goals for run in runs}:
        usual[m] = {}
        for key in runs[0].conditions():
            pool = runs if key != "dataset" else [r for r in runs if r.num_goals == m]
            usual[m][key] = Counter(r.conditions()[key] for r in pool).most_common(1)[0][0]
    return usual


def display_order(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> list[int]:
    """Run indices sorted by agent (the paper's order first, then as given), found budget,
    label, m."""
    known = list(paper.agents)
    first_seen: dict[str, int] = {}
    for run in runs:
        first_seen.setdefault(run.agent, len(first_seen))

    def key(i: int) -> tuple[int, int, int, str, int]:
        run = runs[i]
        rank = known.index(run.agent) if run.agent in known else len(known)
        return (rank, first_seen[run.agent], run.found_budget, labels[i], run.num_goals)

    return sorted(range(len(runs)), key=key)


# ---------------------------------------------------------------------- formatting
def percent(estimate: Estimate) -> str:
    """``mean [low, high]`` in percent."""
    if math.isnan(estimate.mean):  # no episodes
        return "–"
    return f"{100 * estimate.mean:.1f} [{100 * estimate.low:.1f}, {100 * estimate.high:.1f}]"


def signed(estimate: Estimate) -> str:
    """A difference in percentage points, bold when its interval excludes zero."""
    if math.isnan(estimate.mean):
        return "–"
    text = f"{100 * estimate.mean:+.1f} [{100 * estimate.low:+.1f}, {100 * estimate.high:+.1f}]"
    return f"**{text}**" if estimate.excludes_zero() else text


def estimate_record(estimate: Estimate, prefix: str) -> dict[str, float]:
    return {
        f"{prefix}": round(100 * estimate.mean, 4),
        f"{prefix}_low": round(100 * estimate.low, 4),
        f"{prefix}_high": round(100 * estimate.high, 4),
    }


def paired_headline(a: Run, b: Run) -> tuple[int, dict[str, Estimate]] | None:
    """A − B of each headline metric on the episodes both runs played, and how many those are;
    None when they share none."""
    in_b = set(b.episode_ids())
    common = [e for e in a.episode_ids() if e in in_b]
    if not common:
        return None
    differences = {
        key: paired_difference(a.values(key, common), b.values(key, common)) for key, _ in HEADLINE
    }
    return len(common), differences


def noted_pair(table: Table, a: Run, b: Run) -> tuple[int, dict[str, Estimate], str | None] | None:
    """:func:`paired_headline` of ``a`` − ``b`` and its :func:`seeding_note`, that note added to
    ``table``'s; None, with a note saying so, when they share no episodes."""
    compared = paired_headline(a, b)
    if compared is None:
        table.notes.append(f"{a.name} and {b.name} share no episodes: not compared.")
        return None
    note = seeding_note(a, b)
    if note is not None:
        table.notes.append(note)
    return (*compared, note)


def seeding_note(a: Run, b: Run) -> str | None:
    """A note when the agents of ``a`` and ``b`` drew from different seeds on an episode both
    played (:func:`~multion_agents.report.runs.seeding_difference`), None otherwise."""
    in_b = set(b.episode_ids())
    return seeding_difference(a, b, [e for e in a.episode_ids() if e in in_b])


def seed_scheme_note(runs: Sequence[Run]) -> str:
    """How the runs seeded each episode's agent from their seed: by episode id (the same draws in
    every run that holds the episode) or by index (its position in the run's list; every run
    written before ``metrics.json`` recorded the scheme)."""
    by_scheme: dict[str, list[str]] = defaultdict(list)
    for run in runs:
        by_scheme[run.seeding.split(" ", 1)[1].strip("()")].append(run.name)
    if len(by_scheme) == 1:
        (scheme,) = by_scheme
        which = f"every run seeded each episode's agent from its seed by {scheme}"
    else:
        which = "the runs seeded each episode's agent from their seed " + "; ".join(
            f"by {scheme}: {', '.join(names)}" for scheme, names in by_scheme.items()
        )
    meanings = {
        "episode id": "the same draws in every run that holds the episode",
        "index": "by its position in the run's list, so other draws in a run of other episodes",
        "unrecorded": "written before `metrics.json` recorded the scheme",
    }
    present = " ".join(by_scheme)
    told = "; ".join(f"{word}: {meaning}" for word, meaning in meanings.items() if word in present)
    return f"seed: {which} ({told})."


def headline_cells(run: Run, theirs: dict[str, float] | None) -> tuple[list[str], dict[str, Any]]:
    """A run's Success, Progress, SPL and PPL cells (95% intervals) and their CSV fields, with
    the paper's numbers ``theirs`` (percent) in the fields when given."""
    estimates = {key: bootstrap(run.values(key)) for key, _ in HEADLINE}
    fields: dict[str, Any] = {}
    for key, _ in HEADLINE:
        fields.update(estimate_record(estimates[key], key))
        fields[f"paper_{key}"] = theirs[key] if theirs else None
    return [percent(estimates[key]) for key, _ in HEADLINE], fields


def task_label(run: Run) -> str:
    return task_name(run.num_goals).upper()


# ---------------------------------------------------------------------- Table 3
def table3(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table:
    """Agents × m: Success, Progress, SPL, PPL with 95% intervals, the paper's beside them."""
    names = [name for _, name in HEADLINE]
    table = Table(
        "table3",
        "Table 3: Success, Progress, SPL and PPL (%) by agent and task",
        ["agent", "task", "episodes", *(f"{n} %" for n in names), "paper S / P / SPL / PPL"],
    )
    for i in display_order(runs, labels, paper):
        run = runs[i]
        # the paper's Table 3 is for 8 coloured cylinders and no wrong FOUND allowed
        usual = run.found_budget == 0 and run.goal_set == DEFAULT_GOAL_SET
        theirs = paper.table3_row(run.agent, run.num_goals) if usual else None
        cells, fields = headline_cells(run, theirs)
        paper_cell = (
            " / ".join(f"{theirs[key]:.0f}" for key, _ in HEADLINE)
            + f" ({paper.counterpart(run.agent)})"
            if theirs
            else ""
        )
        table.rows.append(
            [
                labels[i],
                task_label(run),
                str(run.count),
                *cells,
                paper_cell,
            ]
        )
        record: dict[str, Any] = {
            "agent": labels[i],
            "task": task_name(run.num_goals),
            "run": run.name,
            "episodes": run.count,
            **run.conditions(),
            **fields,
        }
        table.records.append(record)
    table.notes.append(f"Intervals: {CI_METHOD}.")
    if any(row[-1] for row in table.rows):
        table.notes.append(
            f"Paper columns: {paper.table3['source']}. {paper.setting} Not comparable in "
            "absolute terms: other buildings, other simulator, test set."
        )
    table.notes.extend(mismatch_notes(runs))
    return table


UNRECORDED = ("unknown", "not installed")  # runs without a version of the multion distribution


def mismatch_notes(runs: Sequence[Run]) -> list[str]:
    """One note per way in which the runs differ: conditions, episode counts, versions."""
    notes = []
    for key in runs[0].conditions():
        groups: dict[str, list[str]] = defaultdict(list)
        values_per_m: dict[int, set[str]] = defaultdict(set)
        for run in runs:
            value = run.conditions()[key]
            # the dataset file is per task: only several datasets for one m are a mismatch
            groups[f"{value} ({task_label(run)})" if key == "dataset" else value].append(run.name)
            values_per_m[run.num_goals].add(value)
        if key == "dataset":
            differs = any(len(values) > 1 for values in values_per_m.values())
        else:
            differs = len(groups) > 1
        if differs:
            listing = "; ".join(f"{value}: {', '.join(names)}" for value, names in groups.items())
            notes.append(f"**Runs differ in {key}**, shown as separate rows: {listing}.")
    counts: dict[int, list[str]] = defaultdict(list)
    for run in runs:
        counts[run.count].append(run.name)
    if len(counts) > 1:
        listing = "; ".join(
            f"{count}: {', '.join(names)}" for count, names in sorted(counts.items(), reverse=True)
        )
        notes.append(f"**Episode counts differ** (intervals widen with fewer): {listing}.")
    recorded = {run.multion_version for run in runs if run.multion_version not in UNRECORDED}
    if len(recorded) > 1:
        notes.append(f"**Runs were made with different multion versions**: {sorted(recorded)}.")
    unrecorded = [run.name for run in runs if run.multion_version in UNRECORDED]
    if unrecorded:
        notes.append(f"No multion version recorded for: {', '.join(unrecorded)}.")
    return notes


# ---------------------------------------------------------------------- seen / not seen
def seen_not_seen(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table | None:
    """Success of reaching goal k (k ≥ 2) after goal k-1 was found, split by whether goal k
    was seen before goal k-1 was found (the supplement's backtracking analysis)."""
    table = Table(
        "seen-not-seen",
        "Goal k found after goal k-1: seen before vs not seen (%)",
        ["agent", "task", "goal k", "seen", "not seen", "improvement (points)", "paper seen / not"],
    )
    never_reached: list[str] = []  # goal k-1 never found, so goal k was never looked for
    for i in display_order(runs, labels, paper):
        run = runs[i]
        if run.num_goals < 2:
            continue
        if any("seen_before_current" not in e.metrics for e in run.episodes):
            table.notes.append(f"{run.name}: no per-episode seen_before_current; left out.")
            continue
        missing = []
        for k in range(2, run.num_goals + 1):
            seen, unseen = seen_split(run, k)
            if seen or unseen:
                table.rows.append(_seen_row(table, run, labels[i], k, seen, unseen, paper))
            else:
                missing.append(str(k))
        if missing:
            never_reached.append(f"{labels[i]} on {task_label(run)} (k = {', '.join(missing)})")
    if never_reached:
        table.notes.append(f"Left out, goal k-1 never found: {'; '.join(never_reached)}.")
    if not table.rows:
        return None
    table.notes[:0] = [
        "Among the episodes in which goal k-1 was found, the share that also found goal k, "
        "split by whether goal k had been seen (in the field of view, within the map's view "
        "distance, with a clear line of sight) before goal k-1 was found; n is the number of such episodes. An agent that remembers "
        "what it saw should do better on seen goals. "
        f"Intervals: {CI_METHOD}; the improvement's interval resamples both groups independently.",
    ]
    if any(row[-1] for row in table.rows):
        table.notes.append(f"Paper columns: {paper.seen_not_seen['source']}. {paper.setting}")
    return table


def seen_split(run: Run, goal: int) -> tuple[list[float], list[float]]:
    """:func:`multion.task.measures.seen_split` over the run's episodes."""
    return measures.seen_split((episode.metrics for episode in run.episodes), goal)


def _seen_row(
    table: Table,
    run: Run,
    label: str,
    k: int,
    seen: list[float],
    unseen: list[float],
    paper: PaperResults,
) -> list[str]:
    seen_estimate, unseen_estimate = bootstrap(seen), bootstrap(unseen)
    improvement = independent_difference(seen, unseen)
    theirs = paper.seen_row(run.agent, run.num_goals, k) if run.found_budget == 0 else None
    table.records.append(
        {
            "agent": label,
            "task": task_name(run.num_goals),
            "run": run.name,
            "goal": k,
            "seen_episodes": len(seen),
            "not_seen_episodes": len(unseen),
            **estimate_record(seen_estimate, "seen"),
            **estimate_record(unseen_estimate, "not_seen"),
            **estimate_record(improvement, "improvement"),
            "paper_seen": theirs["seen"] if theirs else None,
            "paper_not_seen": theirs["not_seen"] if theirs else None,
        }
    )
    return [
        label,
        task_label(run),
        str(k),
        f"{percent(seen_estimate)} (n={len(seen)})",
        f"{percent(unseen_estimate)} (n={len(unseen)})",
        signed(improvement),
        f"{theirs['seen']:.0f} / {theirs['not_seen']:.0f}" if theirs else "",
    ]


# ---------------------------------------------------------------------- paired comparisons
def paired(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table | None:
    """For two runs over the same episodes under the same conditions: A − B per metric, with a
    paired bootstrap interval over the episodes both played."""
    names = [name for _, name in HEADLINE]
    table = Table(
        "paired",
        "Paired comparisons on the same episodes: A − B (percentage points)",
        ["A", "B", "task", "common episodes", *(f"Δ {n}" for n in names)],
    )
    groups: dict[tuple[Any, ...], list[int]] = defaultdict(list)
    for i in display_order(runs, labels, paper):
        group = (runs[i].num_goals, *runs[i].conditions().values())
        groups[group].append(i)
    for members in groups.values():
        for position, i in enumerate(members):
            for j in members[position + 1 :]:
                add_pair(table, runs, labels, i, j)
    if not table.rows:
        return None
    table.notes[:0] = [
        "Pairs of runs under the same conditions (task, split, dataset, found budget, goal set, "
        "settings), compared on the episodes both played. Each cell is the mean of A − B over those "
        "episodes with a 95% paired bootstrap interval (episodes resampled jointly for A and B); "
        "**bold**: the interval excludes 0, i.e. the difference is significant at about the 5% "
        "level (one interval per cell, not corrected for the number of comparisons). "
        "A note names each pair whose agents were seeded differently on a shared episode "
        "(`seeded_alike` in the CSV)."
    ]
    return table


def add_pair(
    table: Table,
    runs: Sequence[Run],
    labels: Sequence[str],
    i: int,
    j: int,
    between: dict[str, str] | None = None,
) -> None:
    """A row of ``runs[i]`` − ``runs[j]`` on the episodes both played, or a note that they share
    none; a note too where their agents were seeded differently. ``between``: more cells after
    A and B, by CSV field."""
    between = between or {}
    a, b = runs[i], runs[j]
    compared = noted_pair(table, a, b)
    if compared is None:
        return
    common, differences, note = compared
    table.rows.append(
        [
            labels[i],
            labels[j],
            *between.values(),
            task_label(a),
            str(common),
            *(signed(differences[key]) for key, _ in HEADLINE),
        ]
    )
    record: dict[str, Any] = {
        "a": labels[i],
        "b": labels[j],
        **between,
        "task": task_name(a.num_goals),
        "run_a": a.name,
        "run_b": b.name,
        "common_episodes": common,
        "seeded_alike": note is None,
    }
    for key, _ in HEADLINE:
        record.update(estimate_record(differences[key], f"diff_{key}"))
    table.records.append(record)


# ---------------------------------------------------------------------- the runs themselves
def run_list(runs: Sequence[Run], labels: Sequence[str], paper: PaperResults) -> Table:
    """Which directories went into the report, and their conditions."""
    table = Table(
        "runs",
        "Runs",
        [
            "run",
            "agent",
            "task",
            "episodes",
            "split",
            "dataset",
            "found budget",
            "goal set",
            "settings",
            "seed",
        ],
    )
    for i in display_order(runs, labels, paper):
        run = runs[i]
        conditions = run.conditions()
        row = [
            run.name,
            labels[i],
            task_label(run),
            str(run.count),
            conditions["split"],
            conditions["dataset"],
            conditions["found budget"],
            conditions["goal set"],
            conditions["settings"],
            str(run.seed),
        ]
        table.rows.append(row)
        table.records.append(dict(zip(table.header, row, strict=True)))
    table.notes.append("dataset: the first 12 hex digits of the dataset file's SHA-256 (per task).")
    table.notes.append(seed_scheme_note([runs[i] for i in display_order(runs, labels, paper)]))
    return table
