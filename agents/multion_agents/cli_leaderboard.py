"""``multion leaderboard``: the organisers' commands (:mod:`multion.leaderboard.cli`) and
``baselines``, which plays this package's baseline agents through leaderboard runs."""

from __future__ import annotations

import argparse

from multion.leaderboard import cli as leaderboard_cli
from multion_agents.leaderboard_baselines import play_baselines

add_arguments = leaderboard_cli.add_arguments


def run(args: argparse.Namespace) -> int:
    return leaderboard_cli.run(args, {"baselines": _baselines})


def _baselines(args: argparse.Namespace) -> int:
    db = leaderboard_cli.existing_database(args)
    try:
        run_ids = play_baselines(
            db, args.server, args.track, args.phase, args.agents, not args.quiet
        )
    finally:
        db.close()
    print(f"{leaderboard_cli.counted(len(run_ids), 'baseline run')} played")
    return 0
