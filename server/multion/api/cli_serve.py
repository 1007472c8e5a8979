"""``multion serve``: run a MultiON server with uvicorn (one HTTP process, N simulator workers)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import uvicorn
from fastapi import FastAPI
from pydantic import ValidationError

from multion.api.app import create_app
from multion.api.settings import ServerSettings, fit_outer_memory_limit

# Options that map one-to-one onto ServerSettings fields (None: keep the MULTION_* / default).
_OPTIONS: tuple[tuple[str, type, str], ...] = (
    ("host", str, "address to listen on (default 127.0.0.1; 0.0.0.0 for every interface)"),
    ("port", int, "TCP port (default 8000)"),
    ("workers", int, "simulator worker processes; sessions are spread over them (default 1)"),
    ("max_sessions", int, "most open sessions (default 64)"),
    ("max_envs_per_session", int, "most environments in one session (default 64)"),
    ("max_envs_total", int, "most environments over all sessions (default 256)"),
    ("idle_timeout_s", float, "close sessions unused for this many seconds (default 900)"),
    ("max_request_bytes", int, "largest request body accepted (default 32 MiB)"),
    ("worker_timeout_s", float, "kill and replace a worker silent this long (default 300)"),
    (
        "worker_memory_mb",
        int,
        "address-space limit of each simulator worker, and the room its sessions' memory "
        "estimates share (default 8192, or this process's address-space limit if lower: ulimit -v)",
    ),
    (
        "sessions",
        str,
        "who may open plain sessions: open (anyone, default), token (a team token; needs "
        "--challenge), off (leaderboard runs only)",
    ),
    (
        "sessions_per_client",
        int,
        "plain sessions one client (team token, else IP address) may hold at once (default 16)",
    ),
    (
        "run_reserve",
        float,
        "with --challenge: share of each worker's memory and of --max-sessions that plain "
        "sessions cannot take, kept for leaderboard runs (default 0.5, at most 0.9)",
    ),
    (
        "live_view",
        str,
        "a page per plain session at /v1/live/SESSION_ID (RGB-D, map, metrics as it steps) for "
        "requests from this machine: local, off, or auto (default: local when --host is a "
        "loopback address, else off)",
    ),
    (
        "replica",
        str,
        "this replica's name (1-8 of a-z 0-9) behind a reverse proxy: session and run ids "
        "start with NAME- so the proxy can send them to this replica (default: none)",
    ),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``serve`` options; each also reads ``MULTION_<NAME>`` from the environment."""
    for name, kind, text in _OPTIONS:
        parser.add_argument(f"--{name.replace('_', '-')}", dest=name, type=kind, help=text)
    parser.add_argument(
        "--dataset-dir",
        dest="allowed_dataset_dirs",
        action="append",
        type=Path,
        metavar="DIR",
        help="a directory whose dataset files (and mesh scenes) clients may name in their config; "
        "repeatable. Default: only the packaged datasets",
    )
    parser.add_argument(
        "--log-level",
        default="info",
        choices=["critical", "error", "warning", "info", "debug"],
        help="uvicorn log level (default info)",
    )
    add_http_stack_arguments(parser)
    parser.add_argument(
        "--no-access-log", action="store_true", help="do not log every request (faster)"
    )


def add_http_stack_arguments(parser: argparse.ArgumentParser, whose: str = "") -> None:
    """``--http`` and ``--loop``: uvicorn's HTTP parser and event loop (also for the bench).

    "auto" takes httptools and uvloop when installed (uvicorn[standard]), else h11 and asyncio;
    the explicit choices exist to measure the difference (multion bench --http h11 ...).
    """
    parser.add_argument(
        "--http",
        default="auto",
        choices=["auto", "h11", "httptools"],
        help=f"HTTP parser{whose} (default auto: httptools when installed)",
    )
    parser.add_argument(
        "--loop",
        default="auto",
        choices=["auto", "asyncio", "uvloop"],
        help=f"event loop{whose} (default auto: uvloop when installed)",
    )


def settings_from_args(args: argparse.Namespace) -> ServerSettings:
    """Settings from the options given; the others come from ``MULTION_*`` or the defaults."""
    given = {name: getattr(args, name) for name, _, _ in _OPTIONS}
    given["allowed_dataset_dirs"] = getattr(args, "allowed_dataset_dirs", None)
    return ServerSettings(**{k: v for k, v in given.items() if v is not None})


def checked_settings(args: argparse.Namespace) -> ServerSettings | None:
    """The settings of ``args`` fitted to this process's memory limit; None (and the error
    printed) where they cannot be used."""
    try:
        settings = settings_from_args(args)
    except ValidationError as error:
        print(f"multion serve: invalid option: {error}")
        return None
    try:
        settings, warning = fit_outer_memory_limit(settings)
    except ValueError as error:
        print(f"multion serve: {error}", file=sys.stderr)
        return None
    if warning:
        print(f"multion serve: warning: {warning}", file=sys.stderr)
    return settings


def serve(app: FastAPI, settings: ServerSettings, args: argparse.Namespace) -> int:
    """Serve ``app`` until interrupted; returns the exit status."""
    uvicorn.run(
        app,
        host=settings.host,
        port=settings.port,
        log_level=args.log_level,
        access_log=not args.no_access_log,
        http=getattr(args, "http", "auto"),
        loop=getattr(args, "loop", "auto"),
        timeout_graceful_shutdown=10,
    )
    return 0


def run(args: argparse.Namespace) -> int:
    """A plain session server (``multion serve`` without a challenge; the command itself is
    :mod:`multion.leaderboard.cli_serve`, which can add the leaderboard)."""
    settings = checked_settings(args)
    if settings is None:
        return 2
    try:
        app = create_app(settings)
    except ValueError as error:
        print(f"multion serve: {error}")
        return 2
    return serve(app, settings, args)


def main(argv: list[str] | None = None) -> int:
    """``python -m multion.api.cli_serve``: ``multion serve`` without the leaderboard."""
    parser = argparse.ArgumentParser(prog="multion serve", description=__doc__)
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
