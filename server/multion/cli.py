"""The ``multion`` command line: serve, datasets, scenes, bench, eval, train, submit, leaderboard.

Each sub-command lives in its own module exposing ``add_arguments(parser)`` and ``run(args)``;
modules are imported only when their command runs, so ``multion --help`` stays fast and a
command's heavy dependencies (torch for ``train``) are loaded only when needed.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from multion.processes import exit_on_sigterm

# command name → (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "serve": (
        "multion.api.cli_serve",
        "run a MultiON server (FastAPI + uvicorn, msgpack over HTTP)",
    ),
    "eval": (
        "multion_agents.cli_eval",
        "evaluate an agent on a split, locally or against a server",
    ),
    "train": ("multion_agents.cli_train", "train a learned agent with PPO / DD-PPO"),
    "report": ("multion_agents.cli_report", "tables and figures of the paper from eval runs"),
    "submit": (
        "multion_agents.cli_submit",
        "play an agent through a leaderboard run on a challenge server",
    ),
    "leaderboard": (
        "multion.leaderboard.cli",
        "organisers: database, teams and tokens, runs, export, replay, baselines",
    ),
    "dataset": ("multion.cli_data", "generate or check episode datasets"),
    "scene": ("multion.cli_data", "draw or export scenes"),
    "bench": ("multion.bench", "measure simulator, server and training speed"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="multion",
        description="MultiON: multi-object navigation benchmark on PyBullet (NeurIPS 2020 reproduction).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module_name, help_text) in COMMANDS.items():
        command = sub.add_parser(name, help=help_text, description=help_text)
        # An optional dependency (torch for `train`) may be missing at import or only when the
        # command builds its options; either way only that command becomes unavailable.
        try:
            module = importlib.import_module(module_name)
            add = getattr(module, f"add_{name}_arguments", None) or module.add_arguments
            add(command)
        except ModuleNotFoundError as error:
            reason = f"`multion {name}` is unavailable: {error}"
            if error.name == "torch":
                from multion_agents.registry import SETUP_TORCH

                reason += f"; {SETUP_TORCH}"
            # --help says why; any other option is accepted so that main() can say it too
            command.description = f"{help_text}. {reason}"
            command.set_defaults(_unavailable=reason)
            continue
        command.set_defaults(_run=getattr(module, f"run_{name}", None) or module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    exit_on_sigterm()  # so that servers and workers a command started are stopped with it
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown and not getattr(args, "_unavailable", None):
        parser.error(f"unrecognized arguments: {' '.join(unknown)}")  # as parse_args does
    if args.command is None:
        parser.print_help()
        return 2
    if getattr(args, "_unavailable", None):
        print(args._unavailable, file=sys.stderr)
        return 2
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
