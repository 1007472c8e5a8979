"""``multion eval``: evaluate an agent on a split, against a local or a remote server.

Examples::

    multion eval --agent oracle-planner --task 3-on --split val --episodes 50 --out runs/op
    multion eval --agent explorer --server http://127.0.0.1:8000 --episodes 20
    multion eval --agent my_package.agents:MyAgent --episodes 10
    multion eval --agent random --task 3-on --set task.found_budget=3 --out runs/rand-budget3

Without ``--server`` a server is started on a free loopback port for the run and stopped after.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

SPLITS = ("val", "test", "train")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--agent",
        required=True,
        help="random, random-oracle-found, oracle-planner, explorer, or an import path "
        "'package.module:ClassName' of an Agent subclass",
    )
    parser.add_argument("--task", default="3-on", help="1-on … 8-on (default 3-on)")
    parser.add_argument("--split", default="val", help="dataset split: val or test (default val)")
    parser.add_argument(
        "--episodes", type=int, default=None, help="evaluate N evenly spaced episodes (default all)"
    )
    parser.add_argument(
        "--dataset", default=None, help="a dataset file instead of the packaged one"
    )
    parser.add_argument(
        "--server", default=None, help="server URL, e.g. http://host:8000 (default: start one)"
    )
    parser.add_argument(
        "--in-process",
        action="store_true",
        help="no server: simulate in this process (to debug or profile an agent)",
    )
    parser.add_argument("--out", type=Path, default=None, help="directory for the report files")
    parser.add_argument("--seed", type=int, default=0, help="agent seed (default 0)")
    parser.add_argument(
        "--workers", type=int, default=1, help="episodes played in parallel (default 1)"
    )
    parser.add_argument(
        "--pictures", type=int, default=3, help="top-down pictures of the first N episodes"
    )
    parser.add_argument(
        "--image-size",
        type=int,
        default=None,
        help="camera width = height in pixels (default: the server's, 256 as in the paper)",
    )
    parser.add_argument(
        "--max-steps", type=int, default=None, help="step limit per episode (default 2500)"
    )
    parser.add_argument(
        "--checkpoint",
        default=None,
        help="checkpoint of a learned agent (multion train), e.g. --agent oracle-map "
        "--checkpoint runs/om/checkpoint.pt",
    )
    parser.add_argument(
        "--deterministic",
        action="store_true",
        help="learned agents take the most likely action instead of sampling",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SECTION.FIELD=VALUE",
        help="change the environment config, e.g. --set task.found_budget=3 "
        "--set maps.ego_size=25 --set camera.hfov_deg=90 (repeatable; values are JSON or strings; "
        "recorded in metrics.json)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from multion.task.dataset import DatasetError, parse_task
    from multion_agents.agent import AgentError
    from multion_agents.config_overrides import parse_env_overrides
    from multion_agents.evaluate import check_overrides
    from multion_agents.registry import agent_class
    from multion_client.errors import MultiONError, ServerUnavailable

    try:
        num_goals = parse_task(args.task)
        if args.checkpoint is None:
            agent_class(args.agent)
    except (ValueError, AgentError) as error:
        if args.checkpoint is None and _is_learned(args.agent):
            return _fail(f"{args.agent!r} is a learned agent: give its --checkpoint")
        return _fail(str(error))
    if args.split not in SPLITS and args.dataset is None:
        return _fail(f"unknown split {args.split!r}; splits are {', '.join(SPLITS)}")
    if args.episodes is not None and args.episodes <= 0:
        return _fail(f"--episodes must be positive, got {args.episodes}")
    if args.in_process and args.server is not None:
        return _fail("--in-process and --server exclude each other")
    if args.workers <= 0:
        return _fail(f"--workers must be positive, got {args.workers}")
    try:
        env_overrides = parse_env_overrides(args.set)
        check_overrides(env_overrides)
    except ValueError as error:
        return _fail(str(error))

    from multion_agents.evaluate import EvalSettings, evaluate
    from multion_agents.report.run_summary import format_table, summarize, title_of, write_report

    settings = EvalSettings(
        agent=args.agent,
        num_goals=num_goals,
        split=args.split,
        episodes=args.episodes,
        seed=args.seed,
        server=args.server,
        in_process=args.in_process,
        workers=args.workers,
        dataset=args.dataset,
        image_size=args.image_size,
        max_steps=args.max_steps,
        checkpoint=args.checkpoint,
        deterministic=args.deterministic,
        env_overrides=env_overrides,
    )
    try:
        result = evaluate(settings, progress=not args.quiet)
    except ServerUnavailable as error:
        where = args.server or "the local server"
        return _fail(f"cannot reach {where}: {error}")
    except DatasetError as error:
        hint = "" if args.dataset else (
            f"; only val and test are packaged: make {args.split} episodes with `multion dataset "
            f"generate --task {args.task} --split {args.split} --episodes N --out FILE` and pass "
            "--dataset FILE"
        )  # fmt: skip
        return _fail(f"no episodes to evaluate: {error}{hint}")
    except MultiONError as error:
        return _fail(f"the server refused the evaluation: {error}")
    except (AgentError, ValueError) as error:  # a bad checkpoint (CheckpointError is a ValueError)
        return _fail(str(error))
    except RuntimeError as error:  # a local server that did not start, a dataset mismatch
        return _fail(str(error))
    print(format_table(summarize(result.records), title_of(result)))
    if args.out is not None:
        written = write_report(result, args.out, pictures=args.pictures)
        print(f"wrote {len(written)} files to {args.out}")
    return 0


def _is_learned(name: str) -> bool:
    try:
        from multion_agents.learned.models import MODELS
    except ImportError:  # torch is not installed
        return False
    return name in MODELS


def _fail(message: str) -> int:
    print(f"multion eval: {message}", file=sys.stderr)
    return 2
