"""``multion eval``: evaluate an agent on a split, against a local or a remote server.

Examples::

    multion eval --agent oracle-planner --task 3-on --split val --episodes 50 --out runs/op
    multion eval --agent explorer --server http://127.0.0.1:8000 --episodes 20
    multion eval --agent my_package.agents:MyAgent --episodes 10
    multion eval --agent random --task 3-on --set task.found_budget=3 --out runs/rand-budget3
    multion eval --agent oracle-planner --episodes 10 --out runs/op --video 3

Without ``--server`` a server is started on a free loopback port for the run and stopped after.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from multion_agents.cli_fields import add_options
    from multion_agents.eval_settings import EvalSettings

    add_options(parser, EvalSettings)  # the options of what is evaluated: fields of EvalSettings
    parser.add_argument("--out", type=Path, default=None, help="directory for the report files")
    parser.add_argument(
        "--pictures", type=int, default=3, help="top-down pictures of the first N episodes"
    )
    parser.add_argument(
        "--video", type=int, default=0, metavar="N",
        help="MP4 videos of the first N episodes, replayed from their recorded actions (needs --out)",
    )  # fmt: skip
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from multion.config.datasets import DatasetError, task_name
    from multion.config.errors import UsageError
    from multion_agents.cli_fields import from_options
    from multion_agents.eval_settings import EvalSettings
    from multion_agents.files import output_directory_problem
    from multion_agents.registry import agent_class
    from multion_client.errors import MultiONError, ServerUnavailable

    try:
        if args.checkpoint is None:
            agent_class(args.agent)
        settings = from_options(EvalSettings, args)
    except UsageError as error:
        if args.checkpoint is None and _is_learned(args.agent):
            return _fail(f"{args.agent!r} is a learned agent: give its --checkpoint")
        return _fail(str(error))

    if args.out is not None and (problem := output_directory_problem(args.out)) is not None:
        return _fail(f"--out {args.out}: {problem}")
    if args.video and (problem := _video_problem(args.video, args.out)) is not None:
        return _fail(problem)

    from multion_agents.evaluate import evaluate
    from multion_agents.report.run_summary import format_table, summarize, title_of, write_report

    try:
        result = evaluate(settings, progress=not args.quiet)
    except ServerUnavailable as error:
        where = args.server or "the local server"
        return _fail(f"cannot reach {where}: {error}")
    except DatasetError as error:
        hint = "" if args.dataset else (
            f"; only val and test are packaged: make {args.split} episodes with `multion dataset "
            f"generate --task {task_name(settings.num_goals)} --split {args.split} --episodes N --out FILE` and pass "
            "--dataset FILE"
        )  # fmt: skip
        return _fail(f"no episodes to evaluate: {error}{hint}")
    except UsageError as error:  # a bad checkpoint, a local server that did not start, ...
        return _fail(str(error))
    except MultiONError as error:  # after UsageError: the local config errors are wire errors too
        return _fail(f"the server refused the evaluation: {error}")
    print(format_table(summarize(result.records), title_of(result)))
    if args.out is None:
        return 0
    written = len(write_report(result, args.out, pictures=args.pictures))
    videos = _write_videos(args.out, args.video) if args.video else 0
    if videos is None:
        print(f"wrote {_counted(written, 'report file')} to {args.out}")
        return 2
    made = f": {written} of the report and {_counted(videos, 'video')}" if args.video else ""
    print(f"wrote {_counted(written + videos, 'file')} to {args.out}{made}")
    return 0


def _counted(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _video_problem(count: int, out: Path | None) -> str | None:
    """Why ``--video`` cannot be done, checked before the evaluation starts."""
    from multion.video.encoder import EncoderUnavailable, check_encoder
    from multion_agents.video.film import MAX_VIDEOS

    if not 0 <= count <= MAX_VIDEOS:
        return f"--video must be in [0, {MAX_VIDEOS}], got {count}"
    if out is None:
        return "--video needs --out: the videos are written beside episodes.jsonl"
    try:
        check_encoder()
    except EncoderUnavailable as error:
        return f"--video: {error}"
    return None


def _write_videos(out: Path, count: int) -> int | None:
    """Film the first ``count`` episodes; how many videos were written (None: an error,
    said)."""
    from multion_agents.cli_video import describe
    from multion_agents.video.film import film_run
    from multion_agents.video.recorded import VideoError, read_run

    try:
        films = film_run(read_run(out), count)
    except VideoError as error:
        _fail(f"--video: {error}")
        return None
    for film in films:
        print(describe(film.path, film.frames, film.bytes, film.seconds))
    return len(films)


def _is_learned(name: str) -> bool:
    try:
        from multion_agents.learned.models import MODELS
    except ImportError:  # torch is not installed
        return False
    return name in MODELS


def _fail(message: str) -> int:
    print(f"multion eval: {message}", file=sys.stderr)
    return 2
