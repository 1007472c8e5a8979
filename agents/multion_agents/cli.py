"""The ``multion`` command line: serve, datasets, scenes, bench, eval, video, train, diagnose,
submit, leaderboard.

This is the composition root: it sits in the top package and reaches down into the server's
layers (``multion.leaderboard``, ``multion.api``, ``multion.task`` …), never the reverse.
Each sub-command lives in its own module exposing ``add_arguments(parser)`` and ``run(args)``;
only the module of the command being run is imported, so ``multion --help`` loads neither
PyBullet nor torch (``tests/test_light_imports.py``), and a command's heavy dependencies (torch
for ``train``) are loaded only when it runs.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from dataclasses import dataclass

from multion.common.processes import exit_on_sigterm
from multion_agents.registry import SETUP_TORCH


@dataclass(frozen=True)
class Command:
    """A sub-command: the module that defines its options and runs it, and its one-line help."""

    module: str
    help: str


COMMANDS: dict[str, Command] = {
    "serve": Command(
        "multion.leaderboard.cli_serve",
        "run a MultiON server (FastAPI + uvicorn, msgpack over HTTP)",
    ),
    "eval": Command(
        "multion_agents.cli_eval", "evaluate an agent on a split, locally or against a server"
    ),
    "video": Command(
        "multion_agents.cli_video", "film an episode of an eval run from its recorded actions"
    ),
    "rescore": Command(
        "multion_agents.cli_rescore", "add the task's newer measures to eval runs by replaying them"
    ),
    "train": Command("multion_agents.cli_train", "train a learned agent with PPO / DD-PPO"),
    "diagnose": Command(
        "multion_agents.cli_diagnose",
        "what a learned checkpoint sees and does: goal recall by distance, FOUND calls, endings",
    ),
    "report": Command(
        "multion_agents.cli_report", "tables and figures of the paper from eval runs"
    ),
    "submit": Command(
        "multion_agents.cli_submit",
        "play an agent through a leaderboard run on a challenge server",
    ),
    "leaderboard": Command(
        "multion_agents.cli_leaderboard",
        "organisers: database, teams and tokens, runs, export, replay, baselines",
    ),
    "dataset": Command("multion.task.cli_data", "generate or check episode datasets"),
    "scene": Command("multion.task.cli_data", "draw or export scenes"),
    "bench": Command("multion_agents.bench.cli", "measure simulator, server and training speed"),
}


def build_parser(command_to_load: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command's name and help; the options of ``command_to_load`` only
    (importing its module), so that listing the commands imports none of them."""
    parser = argparse.ArgumentParser(
        prog="multion",
        description="MultiON: multi-object navigation benchmark on PyBullet (NeurIPS 2020 reproduction).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, command in COMMANDS.items():
        command_parser = sub.add_parser(name, help=command.help, description=command.help)
        if name == command_to_load:
            _load_command(name, command, command_parser)
    return parser


def _load_command(name: str, command: Command, parser: argparse.ArgumentParser) -> None:
    # An optional dependency (torch for `train`) may be missing at import or only when the
    # command builds its options; either way only that command becomes unavailable.
    try:
        module = importlib.import_module(command.module)
        add = getattr(module, f"add_{name}_arguments", None) or module.add_arguments
        add(parser)
    except ModuleNotFoundError as error:
        reason = f"`multion {name}` is unavailable: {error}"
        if error.name == "torch":
            reason += f"; {SETUP_TORCH}"
        # --help says why; any other option is accepted so that main() can say it too
        parser.description = f"{command.help}. {reason}"
        parser.set_defaults(_unavailable=reason)
        return
    parser.set_defaults(_run=getattr(module, f"run_{name}", None) or module.run)


def main(argv: list[str] | None = None) -> int:
    exit_on_sigterm()  # so that servers and workers a command started are stopped with it
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv[0] if argv else None)
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
