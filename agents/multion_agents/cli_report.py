"""``multion report``: the paper's tables and figures from ``multion eval`` run directories.

Examples::

    multion report runs/random-3on runs/explorer-3on --out reports/3on
    multion report runs/baselines --out reports/baselines       # every run under runs/baselines
    multion report runs/baselines/* --out docs --doc baselines  # regenerate docs/baselines.md
    multion report runs/pilot runs/central --out reports/x --pair pilot/no-map central/no-map

Writes Table 3 (Success, Progress, SPL, PPL with 95% intervals and the paper's numbers), the
seen / not-seen analysis, the found-budget table (runs differing in ``task.found_budget``),
paired comparisons of agents played on the same episodes (and of the pairs named with
``--pair``, whatever their conditions), and two figures, as Markdown with CSV and PNG files
beside it.
"""

from __future__ import annotations

import argparse
import importlib.util
import shlex
import sys
from pathlib import Path

from multion_agents.files import output_directory_problem
from multion_agents.report.document import DocumentError, Layout, write_report
from multion_agents.report.pairs import find_pairs
from multion_agents.report.paper import paper_results
from multion_agents.report.runs import RunError, load_runs


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "runs",
        nargs="+",
        type=Path,
        metavar="RUN_DIR",
        help="`multion eval --out` directories, or directories holding several of them",
    )
    parser.add_argument("--out", type=Path, required=True, help="directory for the report files")
    parser.add_argument(
        "--doc",
        default=None,
        metavar="NAME",
        help="update the generated part of OUT/NAME.md (between its marker comments) and put "
        "its files in OUT/NAME/, e.g. --out docs --doc baselines",
    )
    parser.add_argument("--no-figures", action="store_true", help="tables only (no matplotlib)")
    parser.add_argument(
        "--pair",
        nargs=2,
        action="append",
        default=[],
        metavar=("RUN_A", "RUN_B"),
        help="also compare these two runs on the episodes both played, whatever their "
        "conditions (a table of their own, naming what differs); each a run directory or the "
        "end of one (central/no-map); repeatable",
    )


def run(args: argparse.Namespace) -> int:
    if args.doc is not None and (not args.doc or "/" in args.doc or args.doc.startswith(".")):
        return _fail(f"--doc {args.doc!r}: give a document name like 'baselines', not a path")
    if not args.no_figures and not has_matplotlib():
        return _fail(
            "the figures need matplotlib: pip install 'multion-pybullet[report]' (scripts/setup.sh does), "
            "or pass --no-figures for the tables alone"
        )
    if (problem := output_directory_problem(args.out)) is not None:
        return _fail(f"--out {args.out}: {problem}")
    try:
        runs = load_runs(args.runs)
        pairs = find_pairs(runs, [tuple(pair) for pair in args.pair])
    except RunError as error:
        return _fail(str(error))
    command = "multion report " + shlex.join(
        [*map(_as_typed, args.runs), "--out", _as_typed(args.out)]
        + (["--doc", args.doc] if args.doc else [])
        + (["--no-figures"] if args.no_figures else [])
        + [word for pair in args.pair for word in ("--pair", *pair)]
    )
    layout = Layout.for_output(args.out, args.doc)
    try:
        written = write_report(runs, paper_results(), layout, command, not args.no_figures, pairs)
    except DocumentError as error:
        return _fail(str(error))
    print(f"{len(runs)} runs → {layout.markdown} (+ {len(written) - 1} files in {layout.assets})")
    return 0


def _as_typed(path: Path) -> str:
    """``path`` relative to the working directory where it lies under it: the command recorded in
    a report is one to run again from there, and names no directory of this machine."""
    absolute = path.resolve()
    cwd = Path.cwd().resolve()
    return str(absolute.relative_to(cwd)) if absolute.is_relative_to(cwd) else str(path)


def has_matplotlib() -> bool:
    return importlib.util.find_spec("matplotlib") is not None


def _fail(message: str) -> int:
    print(f"multion report: {message}", file=sys.stderr)
    return 2
