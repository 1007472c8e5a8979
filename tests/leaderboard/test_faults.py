"""Faults a real deployment meets, small and bounded in time: a SIGTERM to every server process
at once (systemd's ``KillMode=control-group``, a process-group kill) loses nothing and refunds
nothing; killed helper processes are replaced; an unexpected error shows no internal text."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from server_settings import leaderboard_env
from sqlalchemy import select

from multion.api.app import create_app
from multion.api.local_server import LocalServer
from multion.api.settings import ServerSettings
from multion.common.processes import die_with_parent
from multion.leaderboard.app import LeaderboardExtension
from multion.leaderboard.challenge import Challenge
from multion.leaderboard.challenge_file import replace_phase, write_challenge
from multion.leaderboard.cli_serve import SERVE_MODULE
from multion.leaderboard.models import EpisodePicture, Run, utcnow
from multion.leaderboard.run_expiry import RESTART_GRACE
from multion.leaderboard.settings import LeaderboardSettings
from multion.leaderboard.storage import Database, add_team, runs_counted
from multion_client import errors
from multion_client.client import Client
from multion_client.protocol import CONTENT_TYPE, decode, encode
from multion_client.run_protocol import RUNS_PATH, CreateRun, RunObservation, StartEpisode, run_path
from waiting import wait_until


def fault_challenge(challenge: Challenge, directory: Path) -> Path:
    """The tiny challenge, its test-standard phase drawing fresh episodes (through the hidden-
    episode helper) with room for a few runs."""
    standard = challenge.tracks[0].phase("test-standard")
    assert standard is not None
    fresh = dataclasses.replace(standard, total_quota=None, daily_quota=5, episodes_per_run="fresh")
    return write_challenge(replace_phase(challenge, "1-on", fresh), directory / "challenge.toml")


def group_server(challenge_file: Path, database: str) -> LocalServer:
    """A server in its own process group (its workers and helpers join it), ready."""
    server = LocalServer(
        options=["--challenge", str(challenge_file), "--database", database],
        serve_module=SERVE_MODULE,
    )
    server.process = subprocess.Popen(
        server.command, env={**os.environ, **leaderboard_env(), "PYTHONUNBUFFERED": "1"},
        start_new_session=True, preexec_fn=die_with_parent,
    )  # fmt: skip
    return server.wait_ready()


def new_token(database: str, team: str) -> str:
    db = Database.open(database)
    try:
        with db.sessions.begin() as session:
            return add_team(session, team)[1]
    finally:
        db.close()


def runs_of(database: str) -> list[Run]:
    db = Database.open(database)
    try:
        with db.sessions() as session:
            return list(session.scalars(select(Run)))
    finally:
        db.close()


class Player:
    """Plays one run with random moves over its own client (no retries: a failure is seen)."""

    def __init__(self, url: str, token: str, run_id: str, seed: int) -> None:
        self.client = Client(url, token=token, retries=0)
        self.run_id, self.seed = run_id, seed
        self.last: RunObservation | None = None
        self.steps = 0
        self.error: errors.MultiONError | None = None

    def play(self, stop_after: int | None = None) -> None:
        try:
            while self.last is None or not self.last.run_done:
                if stop_after is not None and self.steps >= stop_after:
                    return
                if self.last is None or self.last.done:
                    following = 0 if self.last is None else self.last.episode + 1
                    self.last = self.client.start_episode(self.run_id, following)
                else:
                    action = 1 + (self.seed + self.steps) % 3  # forward, left, right: no FOUND
                    self.last = self.client.run_step(
                        self.run_id, self.last.episode, self.last.seq + 1, action
                    )
                self.steps += 1
        except errors.MultiONError as error:
            self.error = error

    def resume(self, url: str, token: str) -> None:
        """On a restarted server: where the run stands, then on to its end."""
        self.client.close()
        self.client = Client(url, token=token, retries=3)
        self.last = self.client.run_observe(self.run_id)
        self.error = None
        self.play()


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_a_process_group_sigterm_loses_nothing_and_refunds_nothing(
    request: pytest.FixtureRequest, backend: str, challenge: Challenge,
    new_database: Callable[..., str], tmp_path: Path,
) -> None:  # fmt: skip
    challenge_file = fault_challenge(challenge, tmp_path)
    database = new_database(request, backend, tmp_path)
    Database.open(database).close()
    token = new_token(database, "steady")
    server = group_server(challenge_file, database)
    pgid = os.getpgid(server.pid)
    try:
        client = Client(server.url, token=token)
        players = []
        for k, phase in enumerate(("minival", "minival", "test-standard")):
            info = client.create_run(CreateRun("1-on", phase, f"m{k}", sensors=["goal"]))
            players.append(Player(server.url, token, info.run_id, k))
        threads = [threading.Thread(target=p.play) for p in players]
        for thread in threads:
            thread.start()
        wait_until(lambda: min(p.steps for p in players) >= 5 or any(p.error for p in players),
                   timeout=60, interval=0.01, message="5 steps of every player")  # fmt: skip
        assert min(p.steps for p in players) >= 5, [p.error for p in players]
        killed_at = utcnow()
        os.killpg(pgid, signal.SIGTERM)  # every process of the group at once, steps in flight
        assert server.process is not None
        # uvicorn stops in order, then ends by the signal it got (a clean stop for systemd)
        assert server.process.wait(60) in (0, -signal.SIGTERM)
        for thread in threads:
            thread.join(60)
    finally:
        left = _group_left(pgid)
        if left:
            os.killpg(pgid, signal.SIGKILL)
    assert not left, f"processes of the server outlived it: {left}"
    # what the players saw: the server going away (or asked to retry), never a failed run
    for player in players:
        assert player.error is None or isinstance(
            player.error, (errors.ServerUnavailable, errors.WorkerFailed)
        ), player.error
        assert player.error is None or "refunded" not in player.error.message
    stopped = runs_of(database)
    assert {(r.state, r.refunded) for r in stopped} <= {("running", False), ("finished", False)}
    # the runs in play (at least the slowest player's: 5 steps of 80 or more) may wait for the
    # restart: a grace on their step budgets
    in_play = [run for run in stopped if run.state == "running"]
    assert in_play, [(p.steps, p.error) for p in players]
    for run in in_play:
        assert run.deadline is not None and run.deadline > killed_at + RESTART_GRACE, run.deadline
    # after a restart every run goes on where it was and finishes, and counts
    again = group_server(challenge_file, database)
    try:
        for player in players:
            player.resume(again.url, token)
            assert player.error is None and player.last is not None and player.last.run_done
    finally:
        again.stop()
    runs = runs_of(database)
    assert [(r.state, r.refunded) for r in runs] == [("finished", False)] * 3
    assert all(r.summary is not None and r.summary["episodes"] == len(r.order) for r in runs)


def _group_left(pgid: int, wait_s: float = 10.0) -> list[str]:
    """The live (not zombie) processes of a process group after ``wait_s`` at most."""
    with contextlib.suppress(AssertionError):  # the caller says which are left
        wait_until(lambda: not _group_members(pgid), timeout=wait_s, interval=0.2)
    return _group_members(pgid)


def _group_members(pgid: int) -> list[str]:
    """The live (not zombie) processes of a process group: pid and command line."""
    members = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            members.append(
                stat.parent.name
                + " "
                + (stat.parent / "cmdline").read_bytes()[:80].decode(errors="replace")
            )
    return members


def _helpers(server: LocalServer) -> list[int]:
    """The server's helper processes (hidden-episode helper, picture drawer): its spawned
    children that are not simulator workers."""
    workers = {w["pid"] for w in decode(httpx.get(server.url + "/v1/health").content)["workers"]}
    found = []
    for task in Path(f"/proc/{server.pid}/task").iterdir():
        for child in map(int, (task / "children").read_text().split()):
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
            if b"spawn_main" in cmdline and child not in workers:
                found.append(child)
    return found


def test_killed_helpers_are_replaced_and_nothing_is_charged(
    challenge: Challenge, tmp_path: Path
) -> None:
    challenge_file = fault_challenge(challenge, tmp_path)
    database = f"sqlite:///{tmp_path / 'results.db'}"
    Database.open(database).close()
    token = new_token(database, "unlucky")
    server = group_server(challenge_file, database)
    try:
        client = Client(server.url, token=token)
        minival = client.create_run(CreateRun("1-on", "minival", "pics", sensors=["goal"]))
        Player(server.url, token, minival.run_id, 0).play()  # its pictures start the drawer
        standard = client.create_run(CreateRun("1-on", "test-standard", "s", sensors=["goal"]))
        first = Player(server.url, token, standard.run_id, 1)  # drawn by the helper
        first.play(stop_after=1)
        wait_until(lambda: len(_helpers(server)) >= 2, timeout=90, interval=0.2,
                   message="the two helper processes")  # fmt: skip
        helpers = _helpers(server)
        assert len(helpers) == 2, helpers
        for pid in helpers:
            os.kill(pid, signal.SIGKILL)
        time.sleep(0.5)
        # the running run's next episode (a fresh draw) and a new run both work
        while first.last is not None and not first.last.done:
            first.last = first.client.run_step(standard.run_id, first.last.episode,
                                               first.last.seq + 1, 1)  # fmt: skip
        started = first.client.start_episode(standard.run_id, 1)
        assert started.episode == 1 and not started.done
        created = client.create_run(CreateRun("1-on", "test-standard", "t", sensors=["goal"]))
        # and a new minival run gets its pictures from a new drawer
        again = client.create_run(CreateRun("1-on", "minival", "pics2", sensors=["goal"]))
        Player(server.url, token, again.run_id, 2).play()

        def drawn() -> list[EpisodePicture]:
            db = Database.open(database)
            try:
                with db.sessions() as session:
                    return list(session.scalars(select(EpisodePicture).where(
                        EpisodePicture.run_id == again.run_id, EpisodePicture.png != b""
                    )))  # fmt: skip
            finally:
                db.close()

        wait_until(drawn, timeout=120, interval=0.5,
                   message="a picture drawn after the drawer was killed")  # fmt: skip
        assert {r.id: r.state for r in runs_of(database)}[created.run_id] == "running"
        assert not any(r.refunded or r.state == "failed" for r in runs_of(database))
    finally:
        server.stop()


def test_a_helper_that_keeps_failing_charges_no_quota(
    challenge: Challenge, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """In process: the hidden-episode helper fails at every try (even after its pool was
    replaced). A running run fails and is refunded; a new run is not created at all."""
    challenge_file = fault_challenge(challenge, tmp_path)
    database = f"sqlite:///{tmp_path / 'results.db'}"
    Database.open(database).close()
    token = new_token(database, "unlucky")
    leaderboard = LeaderboardSettings(
        challenge=challenge_file, database=database, warm_up=False, draw_pictures=False,
        token_cache_s=0,
    )  # fmt: skip
    app = create_app(ServerSettings(), [LeaderboardExtension(leaderboard)])
    headers = {"authorization": f"Bearer {token}", "content-type": CONTENT_TYPE}
    create = CreateRun("1-on", "test-standard", "m", sensors=["goal"]).to_wire()
    with TestClient(app, raise_server_exceptions=False) as http:

        def post(path: str, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
            answer = http.post(path, content=encode(body), headers=headers)
            return answer.status_code, decode(answer.content)

        code, info = post(RUNS_PATH, create)
        assert code == 201, info

        def broken(*args: object) -> None:
            raise BrokenProcessPool("A child process terminated abruptly, the process pool …")

        monkeypatch.setattr(app.state.runs.hidden, "_run", broken)
        code, started = post(run_path(info["run_id"], "episodes"), StartEpisode(0).to_wire())
        assert code == 500 and "refunded" in started["error"]["message"]
        code, again = post(RUNS_PATH, create)
        assert code == 500 and "no run was created" in again["error"]["message"]
    for answer in (started, again):  # the server's words, never the exception's
        assert "BrokenProcessPool" not in str(answer) and "child process" not in str(answer)
    [run] = runs_of(database)  # the second run was never created
    assert (run.id, run.state, run.end_reason, run.refunded) == (
        info["run_id"],
        "failed",
        "server_error",
        True,
    )
    db = Database.open(database)
    with db.sessions() as session:
        assert runs_counted(session, run.team_id, "1-on", "test-standard", None) == 0
    db.close()


def test_an_unexpected_error_shows_no_internal_text(caplog: pytest.LogCaptureFixture) -> None:
    app = create_app()

    @app.get("/boom")
    async def boom() -> None:
        raise RuntimeError("password=hunter2 at /srv/secret/db.sqlite")

    with caplog.at_level("ERROR", logger="multion.api"):
        answer = TestClient(app, raise_server_exceptions=False).get("/boom")  # no lifespan
    body = decode(answer.content)["error"]
    assert answer.status_code == 500 and body["code"] == "internal_error"
    assert "hunter2" not in answer.text and "RuntimeError" not in body["message"]
    incident = body["message"].split("incident ")[1].split(")")[0]
    assert len(incident) == 8 and f"incident {incident}" in caplog.text and "hunter2" in caplog.text
