"""The two compose stacks of docker/, started with compose as their headers say.

* ``docker-compose.yml``: the agent service plays its episodes against the server service and
  exits 0.
* ``docker-compose.replicas.yml``: PostgreSQL, the one-shot migration, two replicas and nginx. A
  team is added through ``exec`` (``multion leaderboard team add``), ``multion submit`` plays a
  run through nginx on the published port, the replica holding the run is stopped mid-run, the
  run finishes on the other one, and the leaderboard page shows it.

Compose is Debian's ``docker-compose`` (v1). The images are built by the ``images`` fixture
with ``docker build --network host`` (package indexes are reached only through the host's
network here), under the names the compose files give them, and the stacks start with
``--no-build``; that the compose files build from the same Dockerfiles and context is checked
on their resolved config.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
import yaml
from docker_engine import ROOT, Daemon

from multion_client.client import Client
from waiting import wait_until

pytestmark = pytest.mark.slow
DOCKER = ROOT / "docker"


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class Stack:
    """``docker-compose -p PROJECT -f FILE …`` against the test daemon."""

    def __init__(self, daemon: Daemon, file: str, extra_env: dict[str, str]) -> None:
        self.daemon = daemon
        self.project = f"multiontest{os.getpid()}{file.split('.')[1].replace('-', '')}"
        self.file = file
        self.port = free_port()
        self.env = {**daemon.env, **extra_env, "MULTION_PORT": str(self.port)}

    def __call__(
        self, *args: str, timeout: float = 600, check: bool = True
    ) -> subprocess.CompletedProcess[str]:
        command = ["docker-compose", "--no-ansi", "-p", self.project, "-f", self.file, *args]
        result = subprocess.run(
            command, cwd=DOCKER, env=self.env, capture_output=True, text=True, timeout=timeout
        )
        if check and result.returncode != 0:
            raise AssertionError(
                f"{' '.join(command)} exited {result.returncode}\n"
                f"--- stdout\n{result.stdout[-4000:]}\n--- stderr\n{result.stderr[-4000:]}"
            )
        return result

    def down(self) -> None:
        self("down", "-v", "--remove-orphans", check=False)

    def check_builds(self, images: dict[str, str]) -> None:
        """Every service that builds, builds one of ``images`` from its Dockerfile at the root."""
        services = yaml.safe_load(self("config").stdout)["services"]
        built = {s["image"]: s["build"] for s in services.values() if "build" in s}
        assert built, services
        for image, build in built.items():
            assert Path(build["context"]).resolve() == ROOT, build
            assert build["dockerfile"] == images[image], (image, build)


@pytest.fixture
def plain_stack(docker_daemon: Daemon, images: dict[str, str]) -> Iterator[Stack]:
    stack = Stack(docker_daemon, "docker-compose.yml", {})
    try:
        yield stack
    finally:
        stack.down()


def test_compose_agent_plays_against_the_server_and_exits_0(
    plain_stack: Stack, images: dict[str, str]
) -> None:
    plain_stack.check_builds(images)
    started = time.monotonic()
    result = plain_stack("up", "--no-build", "--exit-code-from", "agent", timeout=900)
    print(f"[docker] compose up, 3 episodes: {time.monotonic() - started:.0f} s")
    played = [line for line in result.stdout.splitlines() if "episode val-3-on-" in line]
    assert len(played) == 3, result.stdout[-3000:]


SECRETS = {"MULTION_CHALLENGE_SECRET": "compose-test-secret", "POSTGRES_PASSWORD": "compose-pw"}


@pytest.fixture
def replicas(docker_daemon: Daemon, images: dict[str, str]) -> Iterator[Stack]:
    stack = Stack(docker_daemon, "docker-compose.replicas.yml", SECRETS)
    try:
        stack.check_builds(images)
        started = time.monotonic()
        # -d returns once nginx started: after postgres (healthy), migrate (done) and both
        # replicas (healthy by the image's HEALTHCHECK).
        stack("up", "--no-build", "-d", timeout=900)
        print(f"[docker] replicas stack up: {time.monotonic() - started:.0f} s")
        yield stack
    finally:
        if sys.exc_info()[0] is not None:
            print(stack("logs", "--tail", "40", check=False).stdout)
        stack.down()


def test_replicas_behind_nginx_finish_a_run_when_its_replica_stops(replicas: Stack) -> None:
    added = replicas("exec", "-T", "replica-a", "multion", "leaderboard", "team", "add", "Rocket")
    token = added.stdout.strip().splitlines()[-1]
    assert token.startswith("mlb_"), added.stdout
    url = f"http://127.0.0.1:{replicas.port}"
    submit = subprocess.Popen(
        [sys.executable, "-m", "multion_agents.cli", "submit", "--server", url, "--track", "3-on",
         "--phase", "minival", "--agent", "random", "--method", "compose-random", "--quiet"],
        env={**os.environ, "MULTION_TOKEN": token},
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    try:
        assert submit.stdout is not None
        first = submit.stdout.readline()  # "run a-…: 30 episodes (resume with …)"
        assert first.startswith("run "), first + submit.stdout.read()
        run_id = first.split()[1].rstrip(":")
        holder = f"replica-{run_id.split('-')[0]}"
        with Client(url, token=token) as client:
            wait_until(lambda: client.run_status(run_id).episodes_done >= 2, 300, 0.1, "2 episodes")
            # the participant is paused while its replica stops, so what is left of the run is
            # played on the other one (random's episodes are short: it would finish first)
            os.kill(submit.pid, signal.SIGSTOP)
            done_before = client.run_status(run_id).episodes_done
            assert done_before < 30
            replicas("stop", holder)
            os.kill(submit.pid, signal.SIGCONT)
            output, _ = submit.communicate(timeout=900)
            status = client.run_status(run_id)
        assert submit.returncode == 0, first + output
        assert status.state == "finished", status
        assert status.episodes_done == status.num_episodes > done_before, status
        assert f"run {run_id}: finished" in output
        running = replicas("ps", "--services", "--filter", "status=running").stdout.split()
        assert holder not in running and len({"replica-a", "replica-b"} & set(running)) == 1
        page = httpx.get(f"{url}/leaderboard", timeout=60)
        assert page.status_code == 200
        assert "compose-random" in page.text and "Rocket" in page.text
    finally:
        if submit.poll() is None:
            submit.kill()
            submit.wait()
