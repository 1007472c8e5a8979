"""Two server replicas sharing one PostgreSQL show the same leaderboard, and a run begun on one
continues on the other (rebuilt from the saved actions). Each replica has a name (``--replica``)
that starts the ids it makes, and nginx (docker/nginx.conf, on loopback) routes by it."""

from __future__ import annotations

import os
import re
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from multion.api.local_server import LocalServer, free_port
from multion.leaderboard.storage import Database, add_team
from multion.sim.simulator import Simulator
from multion.task.sampling import sample_episode
from multion_agents.cli_submit import play_run
from multion_agents.registry import agent_class
from multion_client import errors
from multion_client.client import Client
from multion_client.run import RunEnv
from waiting import answers, wait_until

ROOT = Path(__file__).resolve().parents[2]
NGINX = Path("/usr/sbin/nginx")
REQUIRE_NGINX = "MULTION_REQUIRE_NGINX"
NGINX_HINT = (
    f"nginx is not installed ({NGINX}): `apt-get install nginx` (Debian) runs this test; "
    f"{REQUIRE_NGINX}=1 (set by .ci/run) makes it required"
)


@pytest.fixture(scope="module")
def token(postgres_url: str) -> str:
    db = Database.open(postgres_url)
    try:
        with db.sessions.begin() as session:
            return add_team(session, "replicated")[1]
    finally:
        db.close()


@pytest.fixture(scope="module")
def replicas(
    postgres_url: str, challenge_file: Path, launch: Callable[..., Any]
) -> Iterator[dict[str, LocalServer]]:
    """Replicas ``a`` and ``b`` on one PostgreSQL (started one after the other: the first
    migrates the schema). The last test of this module stops one of them."""
    a = launch(challenge_file, postgres_url, {"MULTION_REPLICA": "a"})
    try:
        b = launch(challenge_file, postgres_url, {"MULTION_REPLICA": "b"})
        try:
            yield {"a": a, "b": b}
        finally:
            b.stop()
    finally:
        a.stop()


@pytest.fixture(scope="module")
def session_config() -> dict[str, Any]:
    """A plain session's config: 1 goal in the empty room, a 16×16 camera."""
    grid = Simulator().load_scene("room-6x4")
    rng = np.random.default_rng(3)
    episodes: list[Any] = []
    while not episodes:
        episodes = [e for e in [sample_episode(grid, "room-6x4", 1, rng, "room-0")] if e]
    return {
        "task": {"num_goals": 1, "max_steps": 30},
        "camera": {"width": 16, "height": 16},
        "episodes": [e.to_dict() for e in episodes],
    }


def has_replica(some_id: str, name: str) -> bool:
    return re.fullmatch(rf"{name}-[0-9a-f]+", some_id) is not None and len(some_id) == 32


def test_two_replicas_share_one_postgresql(
    replicas: dict[str, LocalServer], token: str, session_config: dict[str, Any]
) -> None:
    a, b = replicas["a"], replicas["b"]
    done = RunEnv(a.url, "1-on", "minival", "on-a", token=token, sensors=["goal"])
    play_run(done, agent_class("random"), progress=False)
    assert has_replica(done.run_id, "a"), done.run_id
    on_a, on_b = Client(a.url, token=token), Client(b.url, token=token)
    assert on_b.run_status(done.run_id) == on_a.run_status(done.run_id)
    assert [r.run_id for r in on_b.list_runs()] == [r.run_id for r in on_a.list_runs()]
    # the run finished on A is on B's leaderboard page, and its run page shows the same numbers
    board = httpx.get(b.url + "/leaderboard", timeout=60)
    assert board.status_code == 200 and f'data-run="{done.run_id}"' in board.text
    # pictures are drawn in the background after a run ends: compare the pages once drawn,
    # or the two requests may fall on either side of the drawing

    def page_once_drawn() -> str | None:
        page = httpx.get(f"{b.url}/leaderboard/runs/{done.run_id}", timeout=60).text
        return None if "The picture is being drawn" in page else page

    page = wait_until(page_once_drawn, timeout=120, interval=0.5, message="the run's pictures")
    assert page == httpx.get(f"{a.url}/leaderboard/runs/{done.run_id}", timeout=60).text
    assert "on-a" in page and "Results over 3 episodes" in page
    # a run started on A, continued on B at the same step
    going = RunEnv(a.url, "1-on", "minival", "moving", token=token, sensors=["goal", "gps"])
    going.reset()
    observation, *_ = going.step(1)
    moved = RunEnv(b.url, token=token, run_id=going.run_id)
    again, info = moved.reset()
    assert info == {"episode": 0, "seq": 1}
    np.testing.assert_array_equal(again["gps"], observation["gps"])
    moved.step(2)
    assert on_a.run_status(going.run_id).seq == 2
    moved.abandon()
    # a run made by B carries B's name
    other = RunEnv(b.url, "1-on", "minival", "on-b", token=token, sensors=["goal"])
    assert has_replica(other.run_id, "b"), other.run_id
    other.abandon()
    # plain sessions carry their replica's name too, and cannot move
    session = on_b.create_session(session_config)
    try:
        assert has_replica(session.session_id, "b"), session.session_id
        with pytest.raises(errors.SessionNotFound, match="replica 'b' made it"):
            on_a.observe(session.session_id)
    finally:
        on_b.close_session(session.session_id)


# ---------------------------------------------------------------------- nginx on loopback
def test_compose_and_nginx_name_the_same_replicas() -> None:
    """Adding a replica takes a compose service and its nginx lines: none may be forgotten."""
    compose = (ROOT / "docker" / "docker-compose.replicas.yml").read_text()
    conf = (ROOT / "docker" / "nginx.conf").read_text()
    names = re.findall(r"^\s+MULTION_REPLICA: ([a-z0-9]+)", compose, re.MULTILINE)
    assert len(names) >= 2 and len(set(names)) == len(names), names
    for name in names:
        assert re.search(rf"^  replica-{name}:$", compose, re.MULTILINE), name
        assert re.search(
            rf"^      replica-{name}:\n        condition: service_healthy", compose, re.MULTILINE
        ), name
    any_block = re.search(r"upstream multion_any \{(.*?)\}", conf, re.DOTALL)
    assert any_block is not None
    assert sorted(re.findall(r"server replica-([a-z0-9]+):8000", any_block.group(1))) == sorted(
        names
    )
    assert sorted(
        re.findall(r"upstream multion_([a-z0-9]+) \{ server replica-\1:8000[ ;]", conf)
    ) == sorted(names)
    for route, upstream in (("sessions", "multion_"), ("runs", "multion_runs_")):
        pinned = re.findall(rf"~\^/v1/{route}/([a-z0-9]+)-\s+{upstream}\1;", conf)
        assert sorted(pinned) == sorted(names), route
    for name in names:  # a run's replica, then every other replica as a backup
        block = re.search(rf"upstream multion_runs_{name} \{{(.*?)\}}", conf)
        assert block is not None, name
        others = re.findall(r"server replica-([a-z0-9]+):8000 backup;", block.group(1))
        assert sorted(others) == sorted(set(names) - {name}), name


def nginx_config(directory: Path, ports: dict[str, int], listen: int) -> Path:
    """docker/nginx.conf with the replicas' host names and port 80 replaced by loopback ports,
    inside a minimal main config (the official image's nginx.conf includes it the same way)."""
    text = (ROOT / "docker" / "nginx.conf").read_text()
    for name, port in ports.items():
        assert f"replica-{name}:8000" in text, f"docker/nginx.conf has no replica-{name}"
        text = text.replace(f"replica-{name}:8000", f"127.0.0.1:{port}")
    assert "listen 80;" in text
    text = text.replace("listen 80;", f"listen 127.0.0.1:{listen};")
    (directory / "multion.conf").write_text(text)
    main = directory / "nginx.conf"
    main.write_text(
        ("user root;\n" if os.geteuid() == 0 else "")  # workers must reach this temp dir
        + f"pid {directory}/nginx.pid;\nerror_log {directory}/error.log;\n"
        + "events { worker_connections 256; }\n"
        + f"http {{ access_log {directory}/access.log; client_body_temp_path {directory}/body; "
        + f"proxy_temp_path {directory}/proxy; include {directory}/multion.conf; }}\n"
    )
    return main


@pytest.fixture(scope="module")
def nginx_binary() -> Path:
    """/usr/sbin/nginx, else skip (fail with MULTION_REQUIRE_NGINX=1), before any server starts."""
    if not NGINX.exists():
        if os.environ.get(REQUIRE_NGINX) == "1":
            pytest.fail(NGINX_HINT)
        pytest.skip(NGINX_HINT)
    return NGINX


@pytest.fixture(scope="module")
def nginx(
    nginx_binary: Path, replicas: dict[str, LocalServer], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[str]:
    """nginx with docker/nginx.conf on a loopback port in front of the two replicas."""
    directory = tmp_path_factory.mktemp("nginx")
    port = free_port()
    main = nginx_config(directory, {k: s.port for k, s in replicas.items()}, port)
    command = [str(nginx_binary), "-p", str(directory), "-c", str(main)]
    checked = subprocess.run([*command, "-t"], capture_output=True, text=True, timeout=30)
    assert checked.returncode == 0, checked.stderr
    process = subprocess.Popen([*command, "-g", "daemon off;"])
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until(lambda: process.poll() is not None or answers(url + "/v1/health"),
                   timeout=20, message="nginx to answer")  # fmt: skip
        assert process.poll() is None, (directory / "error.log").read_text()
        yield url
    finally:
        process.terminate()
        process.wait(15)


def test_nginx_pins_sessions_and_moves_runs(
    nginx: str,
    replicas: dict[str, LocalServer],
    token: str,
    session_config: dict[str, Any],
) -> None:
    """Through nginx: sessions made on both replicas keep working (each request reaches the
    replica that holds it); a run goes on, and when its replica is stopped, it continues on the
    other one; a session of the stopped replica gets nginx's clear 502. Stops replica of the run,
    so it is the last test of this module."""
    proxy = Client(nginx, token=token)
    sessions = [proxy.create_session(session_config) for _ in range(4)]
    assert {s.session_id[0] for s in sessions} == {"a", "b"}  # least_conn spreads them
    for session in sessions:
        proxy.reset(session.session_id, seeds=[1])
        for action in (1, 2, 1):
            proxy.step(session.session_id, [action])
    run = RunEnv(nginx, "1-on", "minival", "via-nginx", token=token, sensors=["goal", "gps"])
    run.reset()
    observation, *_ = run.step(1)
    holder = run.run_id[0]
    lost = next(s.session_id for s in sessions if s.session_id[0] == holder)
    for session in sessions:
        if session.session_id != lost:
            proxy.close_session(session.session_id)
    replicas[holder].stop()
    moved = RunEnv(nginx, token=token, run_id=run.run_id)  # reaches the other replica
    again, info = moved.reset()
    assert info == {"episode": 0, "seq": 1}
    np.testing.assert_array_equal(again["gps"], observation["gps"])
    moved.step(2)
    assert proxy.run_status(run.run_id).seq == 2
    moved.abandon()
    with pytest.raises(errors.MultiONError, match="cannot move between replicas") as raised:
        proxy.observe(lost)
    assert raised.value.status == 502
    for _ in range(3):  # the other requests reach the replica still up
        assert proxy.health()["status"] == "ok"
