"""Pairs asked for by name (``multion report --pair A B``): two runs compared on the episodes
both played whatever their conditions, with what differs between them named.

The paired table compares only runs under the same conditions, and the image-size table only a
training run with its own camera variant. A question like "the 128² pilot against the 36²
comparison's ``random-oracle-found``" has to be asked.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from multion_agents.report.runs import Run, RunError
from multion_agents.report.stats import HEADLINE
from multion_agents.report.tables import Table, add_pair


def find_run(runs: Sequence[Run], wanted: str) -> int:
    """The index of the run ``wanted`` names: its directory, or the end of its directory's path
    (``no-map``, ``central/no-map``) where no other run's ends the same way."""
    target = Path(wanted)
    if target.is_dir():
        exact = [i for i, run in enumerate(runs) if run.path.resolve() == target.resolve()]
        if exact:
            return exact[0]
    parts = target.parts
    ending = [i for i, run in enumerate(runs) if parts and run.path.parts[-len(parts) :] == parts]
    if len(ending) == 1:
        return ending[0]
    if not ending:
        raise RunError(
            f"--pair {wanted}: no run of the report has that directory (runs: "
            f"{', '.join(run.name for run in runs)})"
        )
    raise RunError(
        f"--pair {wanted}: {len(ending)} runs' directories end so "
        f"({', '.join(str(runs[i].path) for i in ending)}): give more of the path"
    )


def find_pairs(runs: Sequence[Run], wanted: Sequence[tuple[str, str]]) -> list[tuple[int, int]]:
    """``wanted`` (``--pair`` arguments) as indices into ``runs``; a :class:`RunError` names an
    argument that names no run, more than one, or the same run twice."""
    pairs = []
    for first, second in wanted:
        i, j = find_run(runs, first), find_run(runs, second)
        if i == j:
            raise RunError(f"--pair {first} {second}: both name {runs[i].path}")
        pairs.append((i, j))
    return pairs


def differences(a: Run, b: Run) -> str:
    """What differs between the runs' conditions, cameras and agents' settings, ``A vs B`` each:
    ``camera: 128² (gl) vs 36² (tiny)``; "nothing" when they were played alike."""
    mine, theirs = a.conditions_besides_camera(), b.conditions_besides_camera()
    changed = [f"{key}: {mine[key]} vs {theirs[key]}" for key in mine if mine[key] != theirs[key]]
    if a.camera != b.camera:
        changed.append(f"camera: {a.camera} vs {b.camera}")
    if a.agent_settings != b.agent_settings:
        changed.append(f"agent: {a.agent_settings or 'default'} vs {b.agent_settings or 'default'}")
    return "; ".join(changed) or "nothing"


def requested_pairs(
    runs: Sequence[Run], labels: Sequence[str], pairs: Sequence[tuple[int, int]]
) -> Table | None:
    """A − B for each pair asked for, in the order asked; None when none was."""
    if not pairs:
        return None
    names = [name for _, name in HEADLINE]
    table = Table(
        "requested-pairs",
        "Pairs asked for (`--pair`): A − B on the episodes both played (percentage points)",
        ["A", "B", "differs in (A vs B)", "task", "common episodes", *(f"Δ {n}" for n in names)],
    )
    for i, j in pairs:
        add_pair(table, runs, labels, i, j, {"differs_in": differences(runs[i], runs[j])})
    table.notes.insert(
        0,
        "Pairs named with `--pair`, compared whatever their conditions: a difference in "
        "conditions (named in the third column) is part of what the difference measures. Each "
        "cell is the mean of A − B over the episodes both played, with a 95% paired bootstrap "
        "interval; **bold**: the interval excludes 0.",
    )
    return table
