"""Leaderboard fixtures: a tiny challenge (one-room hidden houses, 32×32 camera, 50-step
episodes), a SQLite results database in a temp dir, team tokens, and a real HTTP server."""

from __future__ import annotations

import dataclasses
import datetime as dt
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from server_settings import MAX_REQUEST_BYTES, leaderboard_env

from multion.api.local_server import LocalServer, free_port
from multion.leaderboard.challenge import (
    Challenge,
    HiddenScenes,
    Limits,
    Phase,
    Track,
)
from multion.leaderboard.challenge_file import load_challenge
from multion.leaderboard.challenge_file import write_challenge as write_challenge_file
from multion.leaderboard.cli_serve import SERVE_MODULE
from multion.leaderboard.storage import Database, add_team

SECRET = "test-secret-0123456789abcdef"

TINY = Challenge(
    name="tiny",
    secret=SECRET,
    limits=Limits(max_consecutive_timeouts=2),
    hidden=HiddenScenes(rooms=(1, 1)),
    tracks=(
        Track("1-on", num_goals=1, camera={"width": 32, "height": 32}, max_steps=40, phases=(
            Phase("minival", episodes=3, houses=1, feedback="episodes"),
            # the shared fixture's runs replay the same (test_trust: fresh)
            Phase("test-standard", episodes=2, houses=1, total_quota=1, episodes_per_run="fixed"),
        )),
        Track("1-on-oracle", num_goals=1, kind="oracle", camera={"width": 32, "height": 32},
              max_steps=40, phases=(
            Phase("minival", episodes=2, houses=1, feedback="episodes"),
            Phase("test-challenge", episodes=2, houses=1, feedback="sealed",
                  sealed_until=dt.datetime(2999, 1, 1, tzinfo=dt.timezone.utc),
                  episodes_per_run="fixed"),
        )),
    ),
)  # fmt: skip
"""The tiny challenge: one-room hidden houses, 32×32 camera, 40-step episodes."""


def write_challenge(
    directory: Path, step_timeout_s: float = 60.0, challenge: Challenge = TINY
) -> Path:
    """Write ``challenge`` (default: the tiny one) with ``step_timeout_s`` as
    ``directory/challenge.toml``."""
    limits = dataclasses.replace(challenge.limits, step_timeout_s=step_timeout_s)
    return write_challenge_file(
        dataclasses.replace(challenge, limits=limits), directory / "challenge.toml"
    )


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("leaderboard")


@pytest.fixture(scope="session")
def make_challenge() -> Callable[..., Path]:
    """``make_challenge(directory, step_timeout_s=60.0, challenge=TINY)``: write a challenge
    file (see :func:`write_challenge`)."""
    return write_challenge


@pytest.fixture(scope="module")
def challenge_file(workdir: Path) -> Path:
    return write_challenge(workdir)


@pytest.fixture(scope="module")
def challenge(challenge_file: Path) -> Challenge:
    return load_challenge(challenge_file)


@pytest.fixture(scope="module")
def database(workdir: Path) -> str:
    url = f"sqlite:///{workdir / 'results.db'}"
    Database.open(url).close()
    return url


@pytest.fixture(scope="module")
def new_team(database: str) -> Callable[[str], str]:
    """``new_team(name)`` adds a team and returns its token."""

    def make(name: str) -> str:
        db = Database.open(database)
        try:
            with db.sessions.begin() as session:
                return add_team(session, name)[1]
        finally:
            db.close()

    return make


def start_server(
    challenge_file: Path,
    database: str,
    extra_env: dict[str, str] | None = None,
    options: tuple[str, ...] = (),
) -> LocalServer:
    """A real server with the leaderboard on; tokens are checked at every request."""
    env = {**leaderboard_env(), **(extra_env or {})}
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        server = LocalServer(
            options=["--challenge", str(challenge_file), "--database", database,
                     "--max-request-bytes", str(MAX_REQUEST_BYTES), *options],
            serve_module=SERVE_MODULE,
        )  # fmt: skip
        return server.start()
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


@pytest.fixture(scope="session")
def launch() -> Callable[..., LocalServer]:
    """``launch(challenge_file, database)``: start a server (the caller stops it)."""
    return start_server


@pytest.fixture(scope="module")
def played(server: LocalServer, database: str, new_team: Callable[[str], str]) -> dict[str, Any]:
    """The module's server and database filled by real runs (see played_runs.fill)."""
    from played_runs import fill

    return fill(server.url, database, new_team)


@pytest.fixture(scope="module")
def server(challenge_file: Path, database: str) -> Iterator[LocalServer]:
    server = start_server(challenge_file, database)
    try:
        yield server
    finally:
        server.stop()


# ---------------------------------------------------------------------- PostgreSQL
REQUIRE_POSTGRES = "MULTION_REQUIRE_POSTGRES"
POSTGRES_HINT = (
    "PostgreSQL is not installed: `apt-get install postgresql` (Debian) runs these tests; "
    f"{REQUIRE_POSTGRES}=1 (set by .ci/run) makes them required"
)


def _postgres_bin() -> Path | None:
    found = shutil.which("pg_ctl")
    if found:
        return Path(found).resolve().parent
    versions = sorted(Path("/usr/lib/postgresql").glob("*/bin/pg_ctl"))
    return versions[-1].parent if versions else None


@pytest.fixture(scope="session")
def postgres_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A throwaway PostgreSQL server (initdb + pg_ctl in a temp dir) and an empty database.

    As root (CI), the cluster runs as the ``postgres`` user that Debian's package creates.
    """
    bindir = _postgres_bin()
    if bindir is None:
        if os.environ.get(REQUIRE_POSTGRES) == "1":
            pytest.fail(POSTGRES_HINT)
        pytest.skip(POSTGRES_HINT)
    root = tmp_path_factory.mktemp("postgres")
    data = root / "data"
    prefix: list[str] = []
    if os.geteuid() == 0:
        prefix = ["runuser", "-u", "postgres", "--"]
        shutil.chown(root, "postgres")
        root.chmod(0o700)
        for parent in root.parents:  # postgres must reach its directory
            if parent == Path(tempfile.gettempdir()).parent:
                break
            parent.chmod(parent.stat().st_mode | 0o011)
    port = free_port()

    def run(*command: str) -> None:
        subprocess.run([*prefix, *command], check=True, capture_output=True, timeout=120)

    run(str(bindir / "initdb"), "-D", str(data), "-U", "postgres", "-A", "trust", "-E", "UTF8")
    options = f"-p {port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off"
    run(
        str(bindir / "pg_ctl"),
        "-D",
        str(data),
        "-o",
        options,
        "-l",
        str(root / "log"),
        "-w",
        "start",
    )
    try:
        import psycopg

        with psycopg.connect(
            f"host=127.0.0.1 port={port} user=postgres dbname=postgres", autocommit=True
        ) as conn:
            conn.execute("CREATE DATABASE multion")
        yield f"postgresql+psycopg://postgres@127.0.0.1:{port}/multion"
    finally:
        subprocess.run([*prefix, str(bindir / "pg_ctl"), "-D", str(data), "-m", "fast", "stop"],
                       capture_output=True, timeout=60)  # fmt: skip


@pytest.fixture(scope="session")
def new_database() -> Callable[[pytest.FixtureRequest, str, Path], str]:
    """``new_database(request, backend, directory)``: see :func:`make_database`."""
    return make_database


def make_database(request: pytest.FixtureRequest, backend: str, directory: Path) -> str:
    """An empty database of ``backend``: a SQLite file in ``directory``, or a new database on
    the session's PostgreSQL server (skips without PostgreSQL, as ``postgres_url`` does)."""
    if backend == "sqlite":
        return f"sqlite:///{directory / 'results.db'}"
    server = request.getfixturevalue("postgres_url")
    import secrets

    import psycopg

    name = f"db_{secrets.token_hex(4)}"
    plain = server.replace("postgresql+psycopg", "postgresql").rsplit("/", 1)[0] + "/postgres"
    with psycopg.connect(plain, autocommit=True) as connection:
        connection.execute(f"CREATE DATABASE {name}")
    return server.rsplit("/", 1)[0] + f"/{name}"
