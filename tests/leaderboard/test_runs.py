"""Runs over real HTTP: a baseline plays a phase end to end, its records equal the in-process
env's, every cheat gets a clear 4xx, retries never act twice, a restart loses nothing, a
stored run replays to identical metrics, and every answer is as the OpenAPI document says."""

from __future__ import annotations

import socket
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

import httpx
import numpy as np
import pytest
from sqlalchemy import select

from multion.config.codec import session_config_from_dict
from multion.leaderboard.challenge import Challenge
from multion.leaderboard.hidden import generate_hidden_episodes
from multion.leaderboard.models import EpisodeRecord, Run
from multion.leaderboard.replay import rescore
from multion.leaderboard.storage import Database, find_team, revoke_tokens
from multion.task.env import MultiONEnv
from multion_agents.cli_submit import play_run
from multion_agents.registry import agent_class
from multion_client import errors
from multion_client.client import Client
from multion_client.protocol import CONTENT_TYPE, decode, encode
from multion_client.run import RunEnv
from multion_client.run_protocol import CreateRun, run_path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "api"))
from wire_schema import operation, problems, raw_decode  # noqa: E402  (the API tests' schema checker)


def stored_run(database: str, run_id: str) -> tuple[Run, list[EpisodeRecord]]:
    db = Database.open(database)
    try:
        with db.sessions() as session:
            run = session.get(Run, run_id)
            assert run is not None
            records = list(
                session.scalars(
                    select(EpisodeRecord)
                    .where(EpisodeRecord.run_id == run_id)
                    .order_by(EpisodeRecord.position)
                )
            )
            return run, records
    finally:
        db.close()


def in_process_metrics(
    challenge: Challenge, run: Run, records: list[EpisodeRecord]
) -> list[dict[str, Any]]:
    """The metrics an in-process env gives for the run's episodes and stored actions."""
    track = challenge.track(run.track)
    assert track is not None
    phase = track.phase(run.phase)
    assert phase is not None
    hidden = generate_hidden_episodes(challenge, track, phase)
    config, _ = session_config_from_dict(track.env_config(phase, tuple(run.sensors), run.maps))
    env = MultiONEnv(config, episodes=[hidden[i] for i in run.order])
    out = []
    try:
        for record in records:
            _, info = env.reset(options={"episode_index": record.position})
            for action in record.actions:
                _, _, _, _, info = env.step(int(action))
            out.append(info["metrics"])
    finally:
        env.close()
    return out


def test_a_baseline_plays_a_phase_end_to_end(
    server: Any, challenge: Challenge, database: str, new_team: Callable[[str], str]
) -> None:
    token = new_team("e2e")
    cls = agent_class("random")
    env = RunEnv(server.url, "1-on", "minival", "random", token=token, sensors=list(cls.sensors))
    assert env.num_episodes == 3
    assert set(env.observation_space.spaces) == {"goal"}
    play_run(env, cls, seed=0, progress=False)
    status = env.status()
    assert status.state == "finished" and status.episodes_done == 3
    assert status.results is not None and set(status.results["ppl"]) == {"mean", "low", "high"}
    assert status.episodes is not None and len(status.episodes) == 3  # minival: per episode

    # a retry of the run's very last step (its answer lost) still gets that answer
    last = env.client.run_step(env.run_id, 2, status.seq, 0)
    assert last.run_done and last.done and last.seq == status.seq

    run, records = stored_run(database, env.run_id)
    assert sorted(run.order) == [0, 1, 2]
    assert all(r.actions and set(r.actions) <= set("0123") for r in records)
    for record in records:
        assert record.metrics["end_reason"] in ("success", "wrong_found", "max_steps")
        assert "seen_before_current" in record.metrics
    # the stored records are exactly what the in-process env gives for those actions
    assert [r.metrics for r in records] == in_process_metrics(challenge, run, records)
    # ... and a replay from the database re-scores to identical metrics
    db = Database.open(database)
    try:
        with db.sessions() as session:
            report = rescore(session, challenge, env.run_id, write=False)
    finally:
        db.close()
    assert report["differences"] == [] and report["episodes"] == 3
    assert report["summary"]["ppl"] == run.summary["ppl"]


def test_the_server_sends_only_what_the_track_allows(
    server: Any, new_team: Callable[[str], str]
) -> None:
    token = new_team("peeker")
    env = RunEnv(server.url, "1-on", "test-standard", "peek", token=token)
    observation, info = env.reset()
    assert set(observation) == {"rgb", "depth", "goal", "goal_onehot", "gps", "compass"}
    assert observation["rgb"].shape == (32, 32, 3)
    assert info == {"episode": 0, "seq": 0}  # no episode or scene id, no seed
    raw = httpx.post(
        server.url + run_path(env.run_id, "step"),
        content=encode({"episode": 0, "seq": 1, "action": 2}),
        headers={"authorization": f"Bearer {token}"},
    )
    answer = decode(raw.content)
    assert set(answer) == {
        "episode",
        "seq",
        "observation",
        "done",
        "end_reason",
        "metrics",
        "run_done",
    }
    assert answer["metrics"] is None and answer["end_reason"] is None  # no per-step metrics
    env.abandon()
    status = env.status()
    # test-standard: aggregates only, and an abandoned run counts its missing episodes as failures
    assert status.state == "ended" and status.end_reason == "abandoned"
    assert status.episodes is None and status.results is not None
    assert status.results["end_reasons"] == {"abandoned": 1, "not_played": 1}
    assert status.results["success"]["mean"] == 0.0


def test_sealed_phase_shows_nothing_until_its_date(
    server: Any, new_team: Callable[[str], str]
) -> None:
    token = new_team("sealed")
    env = RunEnv(server.url, "1-on-oracle", "test-challenge", "x", token=token, sensors=["goal"])
    status = env.abandon()
    assert status.state == "ended" and status.results is None and status.episodes is None


def _status(call: Any) -> tuple[int, str]:
    with pytest.raises(errors.MultiONError) as caught:
        call()
    return caught.value.status, caught.value.code


def test_cheats_are_refused(server: Any, database: str, new_team: Callable[[str], str]) -> None:
    token, other = new_team("cheater"), new_team("victim")
    client = Client(server.url, token=token, retries=0)
    info = client.create_run(CreateRun("1-on", "minival", "cheat"))
    url = server.url + run_path(info.run_id, "episodes")
    auth = {"authorization": f"Bearer {token}"}

    def post(path_url: str, body: Any, headers: dict[str, str] = auth) -> tuple[int, str]:
        answer = httpx.post(path_url, content=encode(body), headers=headers)
        return answer.status_code, decode(answer.content)["error"]["code"]

    # a seed or reset options on a run
    assert post(url, {"episode": 0, "seed": 3}) == (403, "not_allowed_in_run")
    assert post(url, {"episode": 0, "options": {"episode_index": 1}}) == (403, "not_allowed_in_run")
    # an oracle sensor on a standard track
    assert _status(lambda: client.create_run(CreateRun("1-on", "minival", "x", ["oracle_map"]))) == (
        403, "not_allowed_in_run",
    )  # fmt: skip
    assert (
        _status(lambda: client.create_run(CreateRun("1-on", "minival", "x", ["goal_distance"])))[0]
        == 403
    )
    # a second episode before the first ends
    client.start_episode(info.run_id, 0)
    assert _status(lambda: client.start_episode(info.run_id, 1)) == (409, "episode_in_progress")
    # a step out of sequence
    assert _status(lambda: client.run_step(info.run_id, 0, 5, 1)) == (409, "sequence_mismatch")
    # another team's run does not exist for it
    intruder = Client(server.url, token=other, retries=0)
    assert _status(lambda: intruder.run_status(info.run_id)) == (404, "run_not_found")
    assert _status(lambda: intruder.run_step(info.run_id, 0, 1, 1)) == (404, "run_not_found")
    assert info.run_id not in [r.run_id for r in intruder.list_runs()]
    # no token, a made-up token, then a revoked one
    assert post(url, {"episode": 0}, headers={}) == (401, "unauthorized")
    assert post(url, {"episode": 0}, headers={"authorization": "Bearer mlb_x_y"}) == (
        401,
        "unauthorized",
    )
    db = Database.open(database)
    with db.sessions.begin() as session:
        revoke_tokens(session, find_team(session, "victim"))
    db.close()
    assert _status(lambda: intruder.list_runs()) == (401, "unauthorized")
    # an oversized body (the server allows 64 KiB here)
    step_url = server.url + run_path(info.run_id, "step")
    assert post(step_url, {"episode": 0, "seq": 1, "action": 1, "pad": "x" * 100_000}) == (
        413, "request_too_large",
    )  # fmt: skip
    # an illegal action, an unknown track
    assert _status(lambda: client.run_step(info.run_id, 0, 1, 7))[0] == 400
    assert _status(lambda: client.create_run(CreateRun("9-on", "minival", "x"))) == (
        404,
        "unknown_track",
    )
    client.abandon_run(info.run_id)
    assert _status(lambda: client.start_episode(info.run_id, 1)) == (409, "run_over")


def test_quota_is_debited_at_creation(server: Any, new_team: Callable[[str], str]) -> None:
    client = Client(server.url, token=new_team("quota"), retries=0)
    first = client.create_run(CreateRun("1-on", "test-standard", "once"))
    client.abandon_run(first.run_id)  # abandoned: still counts
    assert _status(lambda: client.create_run(CreateRun("1-on", "test-standard", "again"))) == (
        429, "quota_exceeded",
    )  # fmt: skip


def _send_and_hang_up(url: str, path: str, token: str, body: dict[str, Any]) -> None:
    """Send a request and close the connection before reading the answer (a dropped link)."""
    parts = urlparse(url)
    payload = encode(body)
    head = (
        f"POST {path} HTTP/1.1\r\nHost: {parts.hostname}\r\nAuthorization: Bearer {token}\r\n"
        f"Content-Type: application/x-msgpack\r\nContent-Length: {len(payload)}\r\n\r\n"
    )
    with socket.create_connection((parts.hostname, parts.port)) as sock:
        sock.sendall(head.encode() + payload)


def test_a_dropped_connection_resumes_without_a_double_step(
    server: Any, database: str, new_team: Callable[[str], str]
) -> None:
    token = new_team("flaky")
    env = RunEnv(server.url, "1-on", "minival", "flaky", token=token, sensors=["goal", "gps"])
    env.reset()
    env.step(1)
    _send_and_hang_up(
        server.url, run_path(env.run_id, "step"), token, {"episode": 0, "seq": 2, "action": 1}
    )
    # the client never saw seq 2's answer: it resumes (a new process) and sends seq 2 again
    resumed = RunEnv(server.url, token=token, run_id=env.run_id)
    client = resumed.client
    again = client.run_step(env.run_id, 0, 2, 1)
    assert again.seq == 2 and not again.done
    assert (
        client.run_step(env.run_id, 0, 2, 1).observation["gps"].tolist()
        == again.observation["gps"].tolist()
    )
    run, _ = stored_run(database, env.run_id)
    assert run.seq == 2 and run.actions == "11"  # acted once per sequence number
    # the crashed client resumes at the same step
    resumed = RunEnv(server.url, token=token, run_id=env.run_id)
    observation, info = resumed.reset()
    assert info == {"episode": 0, "seq": 2}
    np.testing.assert_array_equal(observation["gps"], again.observation["gps"])
    resumed.step(3)
    assert stored_run(database, env.run_id)[0].actions == "113"
    resumed.abandon()


def test_a_server_restart_loses_nothing(
    challenge_file: Path, tmp_path: Path, launch: Callable[..., Any]
) -> None:
    database = f"sqlite:///{tmp_path / 'restart.db'}"
    Database.open(database).close()
    from multion.leaderboard.storage import add_team

    db = Database.open(database)
    with db.sessions.begin() as session:
        token = add_team(session, "persistent")[1]
    db.close()
    first = launch(challenge_file, database)
    try:
        done = RunEnv(first.url, "1-on", "minival", "done", token=token, sensors=["goal"])
        play_run(done, agent_class("random"), progress=False)
        before = done.status()
        going = RunEnv(first.url, "1-on-oracle", "minival", "going", token=token,
                       sensors=["goal", "gps", "compass", "oracle_map"])  # fmt: skip
        going.reset()
        for action in (1, 2, 1, 1):
            observation, *_ = going.step(action)
        crashed = RunEnv(first.url, "1-on", "minival", "crashed", token=token, sensors=["goal"])
        crashed.reset()
        crashed.step(2)
    finally:
        first.stop()
    # a saved state whose last action (a FOUND) ended the episode without its record (as a
    # server that saved actions before their outcome would leave it): the rebuild records it
    db = Database.open(database)
    with db.sessions.begin() as session:
        row = session.get(Run, crashed.run_id)
        lane = row.lanes[0]
        row.lanes = [{**lane, "actions": lane["actions"] + "0", "seq": lane["seq"] + 1}]
    db.close()
    second = launch(challenge_file, database)
    try:
        client = Client(second.url, token=token)
        after = client.run_status(done.run_id)
        assert after.results == before.results and after.episodes == before.episodes
        # the run in progress resumes at the same step, its simulator state rebuilt exactly
        resumed = RunEnv(second.url, token=token, run_id=going.run_id)
        again, info = resumed.reset()
        assert info == {"episode": 0, "seq": 4}
        for key in observation:
            np.testing.assert_array_equal(again[key], observation[key])
        resumed.step(2)
        resumed.abandon()
        # the client retries its lost step: the rebuilt run answers it, with the episode's end
        answer = client.run_step(crashed.run_id, 0, 2, 0)
        assert answer.done and answer.end_reason in ("wrong_found", "success")
        assert answer.metrics is not None and answer.metrics["steps"] == 2
        run, records = stored_run(database, crashed.run_id)
        assert [r.actions for r in records] == ["20"] and run.state == "running"
        client.abandon_run(crashed.run_id)
    finally:
        second.stop()


# ---------------------------------------------------------------------- OpenAPI
def test_every_run_answer_conforms(server: Any, new_team: Callable[[str], str]) -> None:
    document = httpx.get(server.url + "/openapi.json").json()
    token = new_team("documented")
    seen: set[int] = set()

    def send(method: str, path: str, body: Any = None, auth: str | None = token) -> Any:
        spec = operation(document, method, path)
        headers = {"content-type": CONTENT_TYPE}
        if auth:
            headers["authorization"] = f"Bearer {auth}"
        content = None if body is None else encode(body)
        response = httpx.request(method, server.url + path, content=content, headers=headers)
        status = str(response.status_code)
        assert status in spec["responses"], f"{method} {path} answered undocumented {status}"
        schema = spec["responses"][status]["content"][CONTENT_TYPE]["schema"]
        answer = raw_decode(response.content)
        assert not problems(schema, answer), (method, path, status, problems(schema, answer))
        if content is not None and response.status_code < 300:
            request_schema = spec["requestBody"]["content"][CONTENT_TYPE]["schema"]
            assert not problems(request_schema, raw_decode(content)), (method, path, body)
        seen.add(response.status_code)
        return answer

    send("GET", "/v1/challenge", auth=None)
    run = send("POST", "/v1/runs", {"track": "1-on", "phase": "minival", "method": "tour",
                                    "paper_url": "https://example.org/paper"})  # fmt: skip
    rid = run["run_id"]
    send("POST", "/v1/runs", {"track": "1-on", "phase": "minival", "method": "x"}, auth=None)
    send("POST", "/v1/runs", {"track": "1-on", "phase": "minival", "method": "x",
                              "sensors": ["oracle_map"]})  # fmt: skip
    send("POST", "/v1/runs", {"track": "nope", "phase": "minival", "method": "x"})
    send("POST", "/v1/runs", {"track": "1-on", "phase": "minival"})
    send("GET", run_path(rid, "observe"))
    send("POST", run_path(rid, "episodes"), {"episode": 1})
    send("POST", run_path(rid, "episodes"), {"episode": 0, "seed": 1})
    send("POST", run_path(rid, "episodes"), {"episode": 0})
    send("POST", run_path(rid, "episodes"), {"episode": 0})  # a retry: same answer
    send("POST", run_path(rid, "episodes"), {"episode": 1})  # 409: in progress
    send("POST", run_path(rid, "step"), {"episode": 0, "seq": 1, "action": 2})
    send("POST", run_path(rid, "step"), {"episode": 0, "seq": 1, "action": 2})  # retry
    send("POST", run_path(rid, "step"), {"episode": 0, "seq": 3, "action": 2})
    send("POST", run_path(rid, "step"), {"episode": 0, "seq": 2, "action": 9})
    send("POST", run_path(rid, "step"), {"episode": 0, "seq": 2, "action": 1, "pad": "x" * 70_000})
    send("GET", run_path(rid, "observe"))
    send("GET", run_path(rid))
    send("GET", "/v1/runs")
    send("GET", run_path("f" * 32))
    send("DELETE", run_path(rid))
    send("DELETE", run_path(rid))  # 409: over
    assert {200, 201, 400, 401, 403, 404, 409, 413} <= seen
