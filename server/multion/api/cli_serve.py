"""``multion serve``: run a MultiON server with uvicorn (one HTTP process, N simulator workers)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from types import NoneType, UnionType
from typing import Literal, Union, cast, get_args, get_origin

import uvicorn
from fastapi import FastAPI
from pydantic import ValidationError
from pydantic_settings import BaseSettings

from multion.api.app import create_app
from multion.api.settings import ServerSettings, fit_outer_memory_limit
from multion.config.errors import UsageError

DATASET_DIRS = "allowed_dataset_dirs"
"""The one setting whose option is not its name: ``--dataset-dir DIR``, repeatable."""


def settings_options(
    parser: argparse.ArgumentParser,
    settings: type[BaseSettings],
    skip: tuple[str, ...] = (),
    metavars: Mapping[str, str] | None = None,
) -> None:
    """One option per field of ``settings`` (but ``skip``), generated from the field (name,
    type, allowed values, description, default), so that a setting is declared once. An option
    not given is None: the environment variable or the field's default applies."""
    prefix = str(settings.model_config.get("env_prefix", ""))
    for name, field in settings.model_fields.items():
        if name in skip:
            continue
        default = field.get_default(call_default_factory=True)
        shown = "none" if default is None else default
        where = f"env {prefix}{name.upper()}"
        text = f"{field.description} ({where})" if field.is_required() else (
            f"{field.description} (default {shown}; {where})"
        )  # fmt: skip
        flag = f"--{name.replace('_', '-')}"
        metavar = (metavars or {}).get(name)
        if field.annotation is bool:
            action = argparse.BooleanOptionalAction
            parser.add_argument(flag, dest=name, action=action, default=None, help=text)
            continue
        kind, choices = _option_type(field.annotation)
        parser.add_argument(flag, dest=name, type=kind, choices=choices, metavar=metavar, help=text)


def _option_type(annotation: object) -> tuple[Callable[[str], object], tuple[str, ...] | None]:
    """The argparse type and choices of a settings field: int, float, str, Path (or an
    optional one), or a Literal of strings."""
    if get_origin(annotation) is Literal:
        return str, get_args(annotation)
    if get_origin(annotation) in (Union, UnionType):
        (annotation,) = (arg for arg in get_args(annotation) if arg is not NoneType)
    if annotation in (int, float, str, Path):
        return cast(Callable[[str], object], annotation), None
    raise TypeError(f"no command-line form for a setting of type {annotation!r}")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``serve`` options; each also reads ``MULTION_<NAME>`` from the environment."""
    settings_options(parser, ServerSettings, skip=(DATASET_DIRS,))
    parser.add_argument(
        "--dataset-dir",
        dest=DATASET_DIRS,
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
    given = {name: getattr(args, name, None) for name in ServerSettings.model_fields}
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
    except UsageError as error:
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
    except UsageError as error:
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
