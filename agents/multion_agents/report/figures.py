"""The report's figures (PNG, matplotlib without pyplot, so nothing global and no display).

* ``metrics-vs-m.png``: Success, Progress, SPL and PPL against m per agent with 95% interval
  bars, the paper's numbers dotted where the agent has a counterpart (the paper's main finding:
  performance falls as m grows);
* ``episode-lengths.png``: the distribution of episode lengths (steps) per agent, one panel
  per task;
* ``training-curves.png``: train Success (last 100 episodes) against frames for the learned
  agents whose training log (``progress.csv``) is in or beside their run directory.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from multion_agents.learned.training_log import read_csv
from multion_agents.report.paper import PaperResults
from multion_agents.report.runs import Run
from multion_agents.report.stats import HEADLINE, bootstrap
from multion_agents.report.tables import display_order
from multion_client.constants import DEFAULT_GOAL_SET

DPI = 110


def metrics_vs_m(
    runs: Sequence[Run], labels: Sequence[str], paper: PaperResults, path: Path
) -> Path:
    """Each headline metric against m, one line per agent label, interval bars. Labels with a
    single m (e.g. a found-budget variant) have no line to draw and are left to the tables
    (unless no label has more than one)."""
    by_label: dict[str, list[Run]] = defaultdict(list)
    for i in display_order(runs, labels, paper):
        by_label[labels[i]].append(runs[i])
    by_label = {label: members for label, members in by_label.items() if len(members) > 1}
    if not by_label:  # every agent on one task only: one point each
        by_label = {labels[i]: [runs[i]] for i in display_order(runs, labels, paper)}
    tasks = sorted({run.num_goals for run in runs})
    figure = Figure(figsize=(10, 7.2), dpi=DPI, layout="constrained")
    axes = figure.subplots(2, 2, sharex=True).ravel()
    colours = _colours(len(by_label))
    # agents are drawn side by side around each m, so equal values do not hide each other
    shifts = 0.05 * (np.arange(len(by_label)) - (len(by_label) - 1) / 2)
    for axis, (key, name) in zip(axes, HEADLINE, strict=True):
        for colour, shift, (label, members) in zip(colours, shifts, by_label.items(), strict=True):
            members = sorted(members, key=lambda run: run.num_goals)
            m = np.array([run.num_goals for run in members]) + shift
            estimates = [bootstrap(run.values(key)) for run in members]
            mean = np.array([100 * e.mean for e in estimates])
            error = np.array(
                [
                    [100 * (e.mean - e.low) for e in estimates],
                    [100 * (e.high - e.mean) for e in estimates],
                ]
            )
            axis.errorbar(
                m, mean, yerr=error, color=colour, marker="o", capsize=4, label=label, lw=1.8
            )
            theirs = [
                paper.table3_row(run.agent, run.num_goals)
                for run in members
                if run.found_budget == 0 and run.goal_set == DEFAULT_GOAL_SET
            ]
            if theirs and all(theirs):
                axis.plot(
                    m,
                    [row[key] for row in theirs if row],
                    color=colour,
                    ls=":",
                    marker="o",
                    mfc="white",
                    label=f"{paper.counterpart(members[0].agent)} (paper, MP3D test)",
                )
        axis.set_title(name)
        axis.set_ylim(-3, 103)
        axis.set_xticks(tasks, [f"{m}-ON" for m in tasks])
        axis.set_ylabel(f"{name} (%)")
        axis.grid(alpha=0.3)
    handles, names = axes[0].get_legend_handles_labels()
    figure.legend(handles, names, loc="outside lower center", ncols=min(3, len(names)), fontsize=9)
    figure.suptitle("Performance against the number of goals m (95% bootstrap intervals)")
    figure.savefig(path)
    return path


_TICK_LABEL_POINTS = 9
_LABEL_INCHES_PER_CHARACTER = 0.6 * _TICK_LABEL_POINTS / 72  # a character: ~0.6 em wide


def episode_lengths(
    runs: Sequence[Run], labels: Sequence[str], paper: PaperResults, path: Path
) -> Path:
    """Box plots of episode length (steps) per agent label, one panel per task."""
    tasks = sorted({run.num_goals for run in runs})
    order = display_order(runs, labels, paper)
    all_labels = list(dict.fromkeys(labels[i] for i in order))
    colours = dict(zip(all_labels, _colours(len(all_labels)), strict=True))
    # the tick labels (run names, up to ~90 characters) get their own width beside the panels,
    # or constrained layout squeezes the panels to nothing and cuts the names
    label_width = _LABEL_INCHES_PER_CHARACTER * max(len(label) for label in all_labels)
    figure = Figure(
        figsize=(4.2 * len(tasks) + label_width, 1.2 + 0.45 * len(all_labels)),
        dpi=DPI,
        layout="constrained",
    )
    axes = np.atleast_1d(figure.subplots(1, len(tasks), sharey=True, sharex=True))
    longest = max(float(run.values("steps").max()) for run in runs)
    for axis, m in zip(axes, tasks, strict=True):
        members = [i for i in order if runs[i].num_goals == m]
        steps = [np.maximum(runs[i].values("steps"), 1) for i in members]
        positions = [all_labels.index(labels[i]) for i in members]
        boxes = axis.boxplot(
            steps,
            positions=positions,
            orientation="horizontal",
            widths=0.6,
            patch_artist=True,
            whis=(5, 95),
            medianprops={"color": "black"},
        )
        for patch, i in zip(boxes["boxes"], members, strict=True):
            # a box squeezed against the step limit still shows as a thick coloured bar
            patch.set_facecolor((*colours[labels[i]][:3], 0.6))
            patch.set_edgecolor(colours[labels[i]])
            patch.set_linewidth(2.5)
        axis.set_xscale("log")
        axis.set_xlim(0.8, 1.6 * longest)  # room for boxes that sit at the step limit
        axis.set_title(f"{m}-ON")
        axis.set_xlabel("episode length (steps, log scale)")
        axis.grid(alpha=0.3, axis="x")
    axes[0].set_yticks(range(len(all_labels)), all_labels, fontsize=_TICK_LABEL_POINTS)
    axes[0].set_ylim(len(all_labels) - 0.5, -0.5)
    figure.suptitle("Episode lengths: box 25–75%, line median, whiskers 5–95%, dots beyond")
    figure.savefig(path)
    return path


def training_curves(
    runs: Sequence[Run], labels: Sequence[str], paper: PaperResults, path: Path
) -> Path:
    """Train Success (the last 100 training episodes, as ``multion train`` logs it) against
    frames, one line per learned run with a training log; each run's val Success is marked at
    its last frame."""
    order = [i for i in display_order(runs, labels, paper) if runs[i].training_log is not None]
    figure = Figure(figsize=(8, 4.8), dpi=DPI, layout="constrained")
    axis = figure.subplots()
    for colour, i in zip(_colours(len(order)), order, strict=True):
        log = runs[i].training_log
        assert log is not None
        rows = full_windows(read_csv(log))
        if not rows:
            continue
        frames = np.array([r["frames"] for r in rows]) / 1e3
        success = np.array([100 * r["train_success"] for r in rows])
        # a gap (a window refilling after a resume) is left blank, not bridged
        gaps = np.flatnonzero(np.diff([r["update"] for r in rows]) > 1) + 1
        axis.plot(
            np.insert(frames, gaps, np.nan),
            np.insert(success, gaps, np.nan),
            color=colour,
            label=labels[i],
        )
        val = bootstrap(runs[i].values("success"))
        axis.errorbar(
            [frames[-1]],
            [100 * val.mean],
            yerr=[[100 * (val.mean - val.low)], [100 * (val.high - val.mean)]],
            color=colour,
            marker="D",
            capsize=4,
        )
    axis.set_xlabel("training frames (thousands)")
    axis.set_ylabel("Success (%)")
    axis.set_ylim(-3, 103)
    axis.grid(alpha=0.3)
    axis.legend(loc="upper left", fontsize=9)
    figure.suptitle(
        "Train Success (last 100 training episodes); ◆ val Success at the end (95% interval)"
    )
    figure.savefig(path)
    return path


def full_windows(rows: list[dict[str, float]]) -> list[dict[str, float]]:
    """The log's rows of the training that was kept, and only those whose success window is
    full: a resumed run appends from its checkpoint's update again (superseding the rows after
    it) and starts a new window of training episodes."""
    kept: list[dict[str, float]] = []
    for row in rows:
        while kept and kept[-1]["update"] >= row["update"]:
            kept.pop()
        kept.append(row)
    valid = [r for r in kept if np.isfinite(r.get("train_success", np.nan))]
    window = max((r.get("episodes", 0.0) for r in valid), default=0.0)
    return [r for r in valid if r.get("episodes", 0.0) >= window]


def _colours(count: int) -> list[tuple[float, ...]]:
    from matplotlib import colormaps

    palette = colormaps["tab10"] if count <= 10 else colormaps["tab20"]
    return [palette(i % palette.N) for i in range(count)]
