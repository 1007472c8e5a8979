"""Leaderboard trust, round 2, as a hostile participant would try it over real HTTP: hidden
houses never shared between tracks, fresh episodes per run (nothing to replay from one run to
the next), no end reasons that leak results, refunded runs that show nothing, plain sessions
that cannot take the capacity kept for runs, and messages that name no internal id."""

from __future__ import annotations

import dataclasses
import hashlib
import os
import re
import signal
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from multion.api.local_server import LocalServer
from multion.leaderboard.challenge import (
    Challenge,
    HiddenScenes,
    Phase,
    Track,
)
from multion.leaderboard.challenge_file import load_challenge, write_challenge
from multion.leaderboard.hidden import challenge_houses
from multion.leaderboard.replay import rescore
from multion.leaderboard.storage import Database
from multion.scenes.registry import HOUSE_CONFIG, scene_split
from multion_client import errors
from multion_client.client import Client
from multion_client.run_protocol import CreateRun
from waiting import wait_until

SECRET = "trust-secret-0123456789abcdef"

TWO_TRACKS = Challenge(
    name="trust",
    secret=SECRET,
    hidden=HiddenScenes(rooms=(1, 1)),
    tracks=(
        Track("std", num_goals=1, camera={"width": 16, "height": 16}, max_steps=8, phases=(
            Phase("minival", episodes=2, houses=1, feedback="episodes"),
            Phase("test-standard", episodes=3, houses=2, feedback="aggregate"),
            Phase("paired", episodes=3, houses=1, feedback="aggregate", episodes_per_run="fixed"),
        )),
        Track("orc", num_goals=1, kind="oracle", camera={"width": 16, "height": 16}, max_steps=8,
              phases=(Phase("test-standard", episodes=3, houses=2, feedback="aggregate"),)),
    ),
)  # fmt: skip


@pytest.fixture(scope="module")
def trust_challenge(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_challenge(TWO_TRACKS, tmp_path_factory.mktemp("trust") / "challenge.toml")


@pytest.fixture(scope="module")
def trust_server(
    trust_challenge: Path, database: str, launch: Callable[..., LocalServer]
) -> Iterator[LocalServer]:
    server = launch(trust_challenge, database)
    try:
        yield server
    finally:
        server.stop()


def first_views(client: Client, run_id: str, episodes: int) -> list[str]:
    """Play each episode of a run with one FOUND; the hash of each first observation (every
    sensor: two starts facing a bare wall can give the same image, not the same depth)."""
    views = []
    for episode in range(episodes):
        answer = client.start_episode(run_id, episode)
        digest = hashlib.sha256()
        for name in sorted(answer.observation):
            digest.update(name.encode() + answer.observation[name].tobytes())
        views.append(digest.hexdigest())
        assert client.run_step(run_id, episode, 1, 0).done  # FOUND ends it (found or wrong)
    return views


# ---------------------------------------------------------------------- houses
def test_no_two_tracks_or_phases_share_a_hidden_house() -> None:
    challenge = dataclasses.replace(TWO_TRACKS, hidden=HiddenScenes())
    houses = challenge_houses(challenge)
    every = [h for ids in houses.values() for h in ids]
    assert len(every) == len(set(every)) == 2 + 1 + 1 + 2
    # the same phase name on two tracks: different houses (an oracle track cannot map them)
    assert not set(houses[("std", "test-standard")]) & set(houses[("orc", "test-standard")])
    # by default, houses of the packaged generator: plain ids, 8-16 rooms drawn by it
    for house in houses[("std", "minival")]:
        assert re.fullmatch(r"house-\d{10,}", house) and scene_split(house) is None
    # a challenge may narrow the range, within the generator's own
    narrowed = dataclasses.replace(TWO_TRACKS, hidden=HiddenScenes(rooms=(8, 9)))
    rooms = {int(h.rsplit("-r", 1)[1]) for ids in challenge_houses(narrowed).values() for h in ids}
    assert rooms <= {8, 9} and HOUSE_CONFIG.min_rooms == 8


# ---------------------------------------------------------------------- episodes
def test_fresh_runs_never_play_the_same_episodes(
    trust_server: LocalServer, trust_challenge: Path, database: str, new_team: Callable[[str], str]
) -> None:
    client = Client(trust_server.url, token=new_team("prober"))
    runs = [
        client.create_run(CreateRun("std", "test-standard", f"probe {i}", ["rgb", "depth"]))
        for i in range(2)
    ]
    views = [first_views(client, run.run_id, 3) for run in runs]
    assert len(set(views[0])) == 3 and not set(views[0]) & set(views[1])
    # a fixed phase (opted in for paired comparisons) plays one set, reordered
    paired = [
        client.create_run(CreateRun("std", "paired", f"paired {i}", ["rgb", "depth"]))
        for i in range(2)
    ]
    fixed = [first_views(client, run.run_id, 3) for run in paired]
    assert sorted(fixed[0]) == sorted(fixed[1])
    # replay and re-scoring stay exact for fresh runs
    challenge = load_challenge(trust_challenge)
    db = Database.open(database)
    try:
        with db.sessions() as session:
            for run in runs:
                report = rescore(session, challenge, run.run_id, write=False)
                assert report["episodes"] == 3 and report["differences"] == []
    finally:
        db.close()
    info = client.challenge()
    phases = {p["name"]: p["episodes_per_run"] for p in info["tracks"][0]["phases"]}
    assert phases == {"minival": "fixed", "test-standard": "fresh", "paired": "fixed"}


def test_aggregate_phases_send_no_end_reason_that_leaks_a_result(
    trust_server: LocalServer, new_team: Callable[[str], str]
) -> None:
    client = Client(trust_server.url, token=new_team("curious"))
    test = client.create_run(CreateRun("std", "test-standard", "curious", ["goal"]))
    client.start_episode(test.run_id, 0)
    found = client.run_step(test.run_id, 0, 1, 0)
    assert found.done and found.end_reason is None and found.metrics is None
    with pytest.raises(errors.EpisodeOver) as over:  # nor does the error name it
        client.run_step(test.run_id, 0, 2, 1)
    assert "success" not in over.value.message and "wrong_found" not in over.value.message
    client.start_episode(test.run_id, 1)
    answer = None
    for seq in range(1, 9):  # turning until the step limit: that the participant knows
        answer = client.run_step(test.run_id, 1, seq, 2)
    assert answer is not None and answer.done and answer.end_reason == "max_steps"
    minival = client.create_run(CreateRun("std", "minival", "curious", ["goal"]))
    client.start_episode(minival.run_id, 0)
    shown = client.run_step(minival.run_id, 0, 1, 0)
    assert shown.end_reason in ("success", "wrong_found") and shown.metrics is not None


def test_a_refunded_run_shows_nothing_and_names_no_internal_id(
    trust_server: LocalServer, new_team: Callable[[str], str]
) -> None:
    client = Client(trust_server.url, token=new_team("breaker"))
    run = client.create_run(CreateRun("std", "test-standard", "breaker-method", ["goal"]))
    client.start_episode(run.run_id, 0)
    assert client.run_step(run.run_id, 0, 1, 0).done  # one episode recorded
    client.start_episode(run.run_id, 1)
    for worker in client.health()["workers"]:
        os.kill(worker["pid"], signal.SIGKILL)
    with pytest.raises(errors.WorkerFailed) as failed:
        client.run_step(run.run_id, 1, 1, 1)
    assert "refunded" in failed.value.message
    assert not re.search(r"[0-9a-f]{16}", failed.value.message)  # no session or run id
    status = client.run_status(run.run_id)
    assert status.state == "failed" and status.refunded
    assert status.results is None and status.episodes is None
    listed = next(r for r in client.list_runs() if r.run_id == run.run_id)
    assert listed.results is None
    wait_until(lambda: client.health()["status"] == "ok", timeout=30, interval=0.2,
               message="the workers to come back")  # fmt: skip
    with httpx.Client(base_url=trust_server.url) as web:
        page = web.get(f"/leaderboard/runs/{run.run_id}").text
        assert "refunded and shows nothing" in page and "Results over" not in page
        team_page = web.get("/leaderboard/teams/breaker").text
        row = team_page.split(f'data-run="{run.run_id}"', 1)[1].split("</tr>", 1)[0]
        assert "breaker-method" in row and "%" not in row
        assert "breaker-method" not in web.get("/leaderboard").text


# ---------------------------------------------------------------------- capacity
def plain_config() -> dict[str, Any]:
    return {
        "task": {"num_goals": 1},
        "camera": {"width": 16, "height": 16},
        "sensors": ["goal"],
        "split": "val",
    }


def test_plain_sessions_cannot_take_what_runs_need(
    trust_challenge: Path,
    database: str,
    new_team: Callable[[str], str],
    launch: Callable[..., LocalServer],
) -> None:
    options = ("--max-sessions", "10", "--sessions-per-client", "100", "--worker-memory-mb", "2048")
    server = launch(trust_challenge, database, options=options)
    try:
        anonymous = Client(server.url)
        held = []
        with pytest.raises(errors.LimitExceeded) as full:
            for _ in range(12):  # a client with no token opens all it can
                held.append(anonymous.create_session(plain_config()))
        assert "kept for" in full.value.message
        assert 1 <= len(held) <= 5  # half of the memory and of the 10 session slots
        team = Client(server.url, token=new_team("squeezed"))
        run = team.create_run(CreateRun("std", "minival", "squeezed", ["goal"]))
        team.start_episode(run.run_id, 0)
        assert team.run_step(run.run_id, 0, 1, 0).done  # runs still play
    finally:
        server.stop()


def test_plain_sessions_per_client_off_and_token(
    trust_challenge: Path,
    database: str,
    new_team: Callable[[str], str],
    launch: Callable[..., LocalServer],
) -> None:
    server = launch(trust_challenge, database, options=("--sessions-per-client", "2"))
    try:
        anonymous = Client(server.url)
        for _ in range(2):
            anonymous.create_session(plain_config())
        with pytest.raises(errors.TooManySessions, match="sessions_per_client = 2"):
            anonymous.create_session(plain_config())
    finally:
        server.stop()
    server = launch(trust_challenge, database, options=("--sessions", "off"))
    try:
        with pytest.raises(errors.SessionsNotAllowed, match="--sessions off"):
            Client(server.url).create_session(plain_config())
        team = Client(server.url, token=new_team("runs-only"))
        run = team.create_run(CreateRun("std", "minival", "runs-only", ["goal"]))
        team.start_episode(run.run_id, 0)
    finally:
        server.stop()
    server = launch(trust_challenge, database, options=("--sessions", "token"))
    try:
        with pytest.raises(errors.Unauthorized):
            Client(server.url).create_session(plain_config())
        member = Client(server.url, token=new_team("member"))
        assert member.create_session(plain_config()).session_id
    finally:
        server.stop()
