"""Time budgets and server faults, on a server whose runs follow a manual clock: a test
advances it past the step budget instead of sleeping."""

from __future__ import annotations

import os
import signal
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from in_process import InProcessServer

from multion.leaderboard.challenge import Challenge
from multion.leaderboard.clock import ManualClock
from multion.leaderboard.replay import rescore
from multion.leaderboard.storage import Database
from multion_client import errors
from multion_client.client import Client
from multion_client.run import RunEnv
from multion_client.run_protocol import CreateRun
from waiting import wait_until

STEP_TIMEOUT_S = 60.0
LATE = STEP_TIMEOUT_S + 1.0
"""Past one step budget."""


@pytest.fixture(scope="module")
def hasty(
    tmp_path_factory: pytest.TempPathFactory, database: str, make_challenge: Callable[..., Path]
) -> Iterator[InProcessServer]:
    directory = tmp_path_factory.mktemp("hasty")
    challenge = make_challenge(directory, step_timeout_s=STEP_TIMEOUT_S)
    with InProcessServer(challenge, database, ManualClock()) as server:
        yield server


def test_a_late_action_finds_its_episode_scored_as_it_stood(
    hasty: InProcessServer, new_team: Callable[[str], str]
) -> None:
    env = RunEnv(hasty.url, "1-on", "minival", "slow", token=new_team("slow"), sensors=["goal"])
    env.reset()
    env.step(2)
    hasty.clock.advance(LATE)
    with pytest.raises(errors.EpisodeOver, match="timeout"):
        env.client.run_step(env.run_id, 0, 2, 2)
    # RunEnv turns the expiry into a truncated episode, so an agent's loop simply goes on
    _, _, terminated, truncated, info = env.step(2)
    assert truncated and not terminated and info["end_reason"] == "timeout"
    status = env.status()
    assert status.state == "running" and status.episodes_done == 1
    assert status.episodes[0]["metrics"]["end_reason"] == "timeout"
    assert status.episodes[0]["metrics"]["steps"] == 1  # scored as it stood
    _, info = env.reset()
    assert info["episode"] == 1
    assert env.step(1)[4]["seq"] == 1
    env.abandon()


def _replayed_differences(database: str, challenge: Challenge, run_id: str) -> list[int]:
    db = Database.open(database)
    try:
        with db.sessions() as session:
            return list(rescore(session, challenge, run_id, write=False)["differences"])
    finally:
        db.close()


def test_a_silent_client_loses_its_run(
    hasty: InProcessServer, new_team: Callable[[str], str], database: str, challenge: Challenge
) -> None:
    client = Client(hasty.url, token=new_team("silent"))
    info = client.create_run(CreateRun("1-on", "minival", "silent", ["goal"]))
    client.start_episode(info.run_id, 0)
    hasty.clock.advance(LATE)
    # the expiry loop scores the silent episode as it stands; the run goes on
    wait_until(lambda: client.run_status(info.run_id).episodes_done == 1, message="an expiry")
    assert client.run_status(info.run_id).state == "running"
    # two expiries in a row (the episode, then the next one never started) end the run
    hasty.clock.advance(STEP_TIMEOUT_S)
    status = client.run_status(info.run_id)
    assert status.state == "ended" and status.end_reason == "timeouts"
    reasons = [e["metrics"]["end_reason"] for e in status.episodes]
    assert reasons == ["timeout", "timeout", "not_played"]  # missing episodes are failures
    assert status.results["success"]["mean"] == 0.0
    with pytest.raises(errors.RunOver):
        client.start_episode(info.run_id, 1)
    # a sound run replays clean: the episode that expired before it was started is stored
    # as a placeholder, and a replay regenerates the same placeholder (issue 42)
    assert _replayed_differences(database, challenge, info.run_id) == []


def test_a_run_the_server_broke_is_refunded(
    hasty: InProcessServer, new_team: Callable[[str], str]
) -> None:
    client = Client(hasty.url, token=new_team("unlucky"))
    info = client.create_run(CreateRun("1-on", "test-standard", "unlucky", ["goal"]))
    client.start_episode(info.run_id, 0)
    for worker in client.health()["workers"]:
        os.kill(worker["pid"], signal.SIGKILL)
    with pytest.raises(errors.WorkerFailed, match="refunded"):
        client.run_step(info.run_id, 0, 1, 1)
    status = client.run_status(info.run_id)
    assert status.state == "failed" and status.refunded and status.end_reason == "server_error"
    # the phase allows one run in total: the refunded one does not count
    wait_until(lambda: client.health()["status"] == "ok", message="the workers to come back")
    again = client.create_run(CreateRun("1-on", "test-standard", "retry", ["goal"]))
    client.abandon_run(again.run_id)
