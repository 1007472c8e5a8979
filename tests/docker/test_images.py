"""docker/server.Dockerfile and docker/agent.Dockerfile built and run: the server answers
/v1/health from its container and the agent image plays episodes against it."""

from __future__ import annotations

import os
import re

import pytest
from docker_engine import Daemon

pytestmark = pytest.mark.slow
HEALTH = (
    "import httpx, sys; answer = httpx.get('http://127.0.0.1:8000/v1/health'); "
    "print(answer.status_code)"
)

GL_OPENS = "from multion.sim.camera import why_not_gl; print(why_not_gl())"


def test_the_agent_image_plays_against_the_server_image(
    docker_daemon: Daemon, images: dict[str, str]
) -> None:
    name = f"multion-test-{os.getpid()}"
    docker_daemon.run("docker", "network", "create", name)
    try:
        docker_daemon.run(
            "docker", "run", "-d", "--name", f"{name}-server", "--network", name,
            "--network-alias", "server", "multion-server",
        )  # fmt: skip
        # The agent waits for the server's health (its workers import the simulator).
        agent = docker_daemon.run(
            "docker", "run", "--rm", "--network", name, "-e", "MULTION_SERVER=http://server:8000",
            "-e", "MULTION_EPISODES=3", "-e", "MULTION_TASK=2", "multion-agent", timeout=600,
        )  # fmt: skip
        episodes = re.findall(r"episode (val-2-on-\d+): success \d progress [\d.]+", agent.stdout)
        assert len(episodes) == 3, agent.stdout + agent.stderr
        health = docker_daemon.run("docker", "exec", f"{name}-server", "python", "-c", HEALTH)
        assert health.stdout.strip() == "200"
        user = docker_daemon.run("docker", "exec", f"{name}-server", "id", "-un")
        assert user.stdout.strip() == "multion"  # not root
        # the gl renderer opens (Mesa's llvmpipe through EGL, no GPU): MultiON 2.0's tracks
        gl = docker_daemon.run("docker", "exec", f"{name}-server", "python", "-c", GL_OPENS)
        assert gl.stdout.strip() == "None", gl.stdout + gl.stderr
    finally:
        docker_daemon.run("docker", "rm", "-f", f"{name}-server", check=False)
        docker_daemon.run("docker", "network", "rm", name, check=False)
