"""``multion rescore``: add the measures the task has gained to ``multion eval`` runs.

Examples::

    multion rescore runs/no-map                     # adds e.g. current_goal_seen to its lines
    multion rescore docs/learned/pilot/*/ --check   # only check that every episode replays

Each episode's recorded actions are played again in this process, without its agent and
without rendering; every metric the run recorded must come out the same, or the run is left as
it was and the error names the episode. Only then are the measures it lacked added to
``episodes.jsonl`` (and noted in ``metrics.json`` as ``run.rescored``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "run_dirs", type=Path, nargs="+", metavar="RUN_DIR", help="`multion eval --out` directories"
    )
    parser.add_argument(
        "--check", action="store_true",
        help="replay and compare only; write nothing",
    )  # fmt: skip
    parser.add_argument(
        "--dataset", type=Path, default=None,
        help="the dataset file the runs played, where their recorded path is not valid here",
    )  # fmt: skip
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from multion_agents.rescore import rescore_run, write_rescored
    from multion_agents.video.recorded import VideoError, read_run

    failed = 0
    for path in args.run_dirs:
        try:
            recorded = read_run(path, args.dataset)
            with tqdm(total=len(recorded.episodes), desc=str(path), unit="ep",
                      disable=args.quiet) as bar:  # fmt: skip
                rescored = rescore_run(recorded, lambda: bar.update(1))
        except VideoError as error:
            print(f"multion rescore: {path}: {error}", file=sys.stderr)
            failed += 1
            continue
        count = len(rescored.lines)
        if not rescored.added:
            print(f"{path}: {count} episodes replayed as recorded; no measure to add")
        elif args.check:
            print(f"{path}: {count} episodes replayed as recorded; would add "
                  f"{', '.join(rescored.added)}")  # fmt: skip
        else:
            write_rescored(rescored)
            print(f"{path}: {count} episodes replayed as recorded; added "
                  f"{', '.join(rescored.added)}")  # fmt: skip
    return 2 if failed else 0
