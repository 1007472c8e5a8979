"""Leaderboard fixtures: a tiny challenge (one-room hidden houses, 32×32 camera, 50-step
episodes), a SQLite results database in a temp dir, team tokens, and a real HTTP server."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from multion.api.local_server import LocalServer
from multion.leaderboard.challenge import Challenge, load_challenge
from multion.leaderboard.storage import Database, add_team

SECRET = "test-secret-0123456789abcdef"

CHALLENGE = """
[challenge]
name = "tiny"
secret = "{secret}"

[limits]
step_timeout_s = {step_timeout_s}
max_consecutive_timeouts = 2

[hidden]
rooms = [1, 1]

[[tracks]]
name = "1-on"
num_goals = 1
kind = "standard"
camera = {{ width = 32, height = 32 }}
max_steps = 40

[[tracks.phases]]
name = "minival"
episodes = 3
houses = 1
feedback = "episodes"

[[tracks.phases]]
name = "test-standard"
episodes = 2
houses = 1
feedback = "aggregate"
total_quota = 1

[[tracks]]
name = "1-on-oracle"
num_goals = 1
kind = "oracle"
camera = {{ width = 32, height = 32 }}
max_steps = 40

[[tracks.phases]]
name = "minival"
episodes = 2
houses = 1
feedback = "episodes"

[[tracks.phases]]
name = "test-challenge"
episodes = 2
houses = 1
feedback = "sealed"
sealed_until = 2999-01-01T00:00:00Z
"""


def write_challenge(directory: Path, step_timeout_s: float = 60.0) -> Path:
    path = directory / "challenge.toml"
    path.write_text(CHALLENGE.format(secret=SECRET, step_timeout_s=step_timeout_s))
    return path


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("leaderboard")


@pytest.fixture(scope="session")
def make_challenge() -> Callable[..., Path]:
    """``make_challenge(directory, step_timeout_s=60.0)``: write the tiny challenge file."""
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
    challenge_file: Path, database: str, extra_env: dict[str, str] | None = None
) -> LocalServer:
    """A real server with the leaderboard on; tokens are checked at every request."""
    env = {
        "MULTION_LEADERBOARD_TOKEN_CACHE_S": "0",
        "MULTION_LEADERBOARD_EXPIRE_INTERVAL_S": "0.2",
        **(extra_env or {}),
    }
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        server = LocalServer(
            options=["--challenge", str(challenge_file), "--database", database,
                     "--max-request-bytes", "65536"],
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
def server(challenge_file: Path, database: str) -> Iterator[LocalServer]:
    server = start_server(challenge_file, database)
    try:
        yield server
    finally:
        server.stop()
