"""``multion serve``: a MultiON session server, with the leaderboard when given a challenge.

The session server's options and its plain form are :mod:`multion.api.cli_serve`; this module
adds ``--challenge`` and ``--database`` and composes the app with the leaderboard's extension,
so that ``multion.api`` never imports the leaderboard.
"""

from __future__ import annotations

import argparse
import os

from pydantic import ValidationError

from multion.api import cli_serve
from multion.api.app import create_app
from multion.config.errors import UsageError
from multion.leaderboard.app import LeaderboardExtension
from multion.leaderboard.settings import LeaderboardSettings

SERVE_MODULE = __name__
"""What ``LocalServer(serve_module=...)`` runs for a server that may hold leaderboard runs."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The session server's options, then the leaderboard's."""
    cli_serve.add_arguments(parser)
    metavars = {"challenge": "FILE", "database": "URL"}
    cli_serve.settings_options(parser, LeaderboardSettings, metavars=metavars)


def run(args: argparse.Namespace) -> int:
    """Serve until interrupted; returns the exit status."""
    # the leaderboard is on with --challenge or $MULTION_LEADERBOARD_CHALLENGE (docs' Serving)
    challenge_file = args.challenge or os.environ.get("MULTION_LEADERBOARD_CHALLENGE")
    if not (challenge_file or args.database):
        return cli_serve.run(args)
    settings = cli_serve.checked_settings(args)
    if settings is None:
        return 2
    if not challenge_file:
        print("multion serve: --database needs --challenge FILE")
        return 2
    given = {name: getattr(args, name, None) for name in LeaderboardSettings.model_fields}
    given["challenge"] = challenge_file
    try:
        leaderboard = LeaderboardSettings(**{k: v for k, v in given.items() if v is not None})
        app = create_app(settings, [LeaderboardExtension(leaderboard)])
    except (ValidationError, UsageError) as error:
        print(f"multion serve: {error}")
        return 2
    return cli_serve.serve(app, settings, args)


def main(argv: list[str] | None = None) -> int:
    """``python -m multion.leaderboard.cli_serve``: the same as ``multion serve``."""
    parser = argparse.ArgumentParser(prog="multion serve", description=__doc__)
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
