"""Fixtures of the Docker tests: one private daemon, the stand-in base images and the project's
two images, built once per test session (see ``docker_engine.py``)."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator

import pytest
from docker_engine import (
    REQUIRE_DOCKER,
    ROOT,
    SYSTEM_PARTS,
    Daemon,
    ensure_standins,
    missing_tools,
    start_daemon,
)

# image tag → Dockerfile, as docker/README.md builds them
IMAGES = {"multion-server": "docker/server.Dockerfile", "multion-agent": "docker/agent.Dockerfile"}


def _unavailable(reason: str) -> None:
    message = f"{reason}: install {SYSTEM_PARTS} (apt-get install -y {SYSTEM_PARTS}), as root"
    if os.environ.get(REQUIRE_DOCKER) == "1":
        pytest.fail(f"{REQUIRE_DOCKER}=1 but {message}")
    pytest.skip(message)


@pytest.fixture(scope="session")
def docker_daemon() -> Iterator[Daemon]:
    """A private dockerd with the stand-ins of python:3.11-slim, postgres:16 and nginx:1.27."""
    missing = missing_tools()
    if missing:
        _unavailable(f"the Docker tests need {', '.join(missing)}")
    if os.geteuid() != 0:
        _unavailable("the Docker tests start their own dockerd, which needs root")
    daemon = start_daemon()
    try:
        for step, seconds in ensure_standins(daemon).items():
            print(f"[docker] {step}: {seconds:.0f} s")
        yield daemon
    finally:
        daemon.stop()


@pytest.fixture(scope="session")
def images(docker_daemon: Daemon) -> dict[str, str]:
    """The server and agent images, built from the repository's Dockerfiles (package indexes
    are reached through the host's network)."""
    for tag, dockerfile in IMAGES.items():
        started = time.monotonic()
        docker_daemon.run(
            "docker", "build", "--network", "host", "-q", "-f", dockerfile, "-t", tag, ".",
            cwd=ROOT, timeout=1500,
        )  # fmt: skip
        print(f"[docker] build {tag}: {time.monotonic() - started:.0f} s")
    return IMAGES
