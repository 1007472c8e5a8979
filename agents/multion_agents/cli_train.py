"""``multion train``: train a learned agent with PPO, or DD-PPO under ``torchrun``.

Examples::

    multion train --agent oracle-map --task 1-on --frames 2000000 --envs 4 --out runs/om
    multion train --agent oracle-map --task 1-on --frames 2000000 --out runs/om --resume
    multion train --agent no-map --server http://gpu-box:8000 --server http://gpu-box:8001 --envs 8
    torchrun --nproc-per-node 2 -m multion_agents.cli train --agent oracle-map --envs 2 --out runs/ddppo

Every rank of a ``torchrun`` job steps ``--envs`` environments of its own; only rank 0 writes
logs and checkpoints.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from multion_agents.cli_fields import add_options
    from multion_agents.learned.train_settings import Args

    parser.add_argument("--list", action="store_true", help="list the learned agents and exit")
    add_options(parser, Args)  # every other option is a field of Args


def run(args: argparse.Namespace) -> int:
    from multion.config.datasets import parse_task
    from multion.config.errors import UsageError
    from multion_agents.cli_fields import from_options
    from multion_agents.files import output_directory_problem
    from multion_agents.learned.models import MODELS
    from multion_agents.learned.train_settings import Args
    from multion_agents.learned.training_run import train
    from multion_agents.periodic_eval import ValEvaluation

    if args.list:
        for name, spec in MODELS.items():
            print(f"{name:28s} {spec.paper_name}")
        return 0
    try:
        settings = from_options(Args, args, extra={"argv": sys.argv})
    except UsageError as error:
        return _fail(str(error))
    if settings.agent not in MODELS:
        return _fail(f"unknown learned agent {settings.agent!r}; known: {', '.join(MODELS)}")
    if (problem := output_directory_problem(Path(settings.out))) is not None:
        return _fail(f"--out {settings.out}: {problem}")
    try:
        evaluation = ValEvaluation(settings.eval_episodes, settings.seed, parse_task(settings.task))
        summary = train(settings, evaluation)
    except UsageError as error:  # a bad checkpoint, resume or option; anything else is a bug
        return _fail(str(error))
    if "fps" in summary:
        print(
            f"trained {settings.agent} on {settings.task}: {summary['frames']} frames, "
            f"{summary['fps']:.0f} frames/s in the last update; run directory {settings.out}"
        )
    elif settings.resume:  # an interrupted script running it again (scripts/*.sh) goes on
        print(
            f"{settings.out} already holds {summary['frames']} frames (--frames "
            f"{settings.frames}): nothing to train"
        )
    return 0


def _fail(message: str) -> int:
    print(f"multion train: {message}", file=sys.stderr)
    return 2
