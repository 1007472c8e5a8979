"""Bad input is the client's 4xx; a bug in the simulator is a logged 500 with a generic body."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from msgpack_calls import post

from multion.api import worker_process
from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion.api.workers import Worker
from multion.task.env import MultiONEnv
from multion.task.errors import BadResetOptionError, EpisodeNotFoundError, TaskError
from multion_client.protocol import session_path

SETTINGS = ServerSettings(workers=1, max_sessions=2, max_envs_per_session=2, idle_timeout_s=600)
SECRET = "password=hunter2 in /srv/secret"


@pytest.fixture(scope="module")
def api() -> Iterator[TestClient]:
    with TestClient(create_app(SETTINGS), raise_server_exceptions=False) as client:
        yield client


def test_task_errors_keep_their_builtins() -> None:
    assert issubclass(BadResetOptionError, (TaskError, ValueError))
    assert issubclass(EpisodeNotFoundError, (TaskError, ValueError))


def test_worker_answers_a_bug_with_a_generic_message_and_the_traceback(
    small_config: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    shards: dict[str, worker_process.Shard] = {}
    payload = {"config": small_config, "num_envs": 1, "auto_reset": False}
    assert worker_process.handle(shards, "create", "s", payload)[0]["ok"]
    reset = {"seeds": [None], "options": [{"episode_id": "nope"}]}
    header, _ = worker_process.handle(shards, "reset", "s", reset)
    assert header["code"] == "invalid_episode" and "traceback" not in header
    worker_process.handle(shards, "reset", "s", {"seeds": [None], "options": [None]})

    def broken_step(self: MultiONEnv, action: int) -> None:
        raise KeyError(SECRET)

    monkeypatch.setattr(MultiONEnv, "step", broken_step)
    header, _ = worker_process.handle(shards, "step", "s", {"actions": [1]})
    assert (
        header["code"] == "internal_error"
        and header["message"] == "the simulator failed on this request"
    )
    assert SECRET in header["traceback"] and "broken_step" in header["traceback"]
    worker_process.handle(shards, "close", "s", None)


def test_server_logs_a_simulator_bug_and_answers_500(
    api: TestClient,
    small_config: dict[str, Any],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    status, body = post(api, "/v1/sessions", {"config": small_config, "num_envs": 1})
    assert status == 201, body
    sid = body["session_id"]
    assert post(api, session_path(sid, "reset"), {})[0] == 200
    # a bad reset option stays the client's 400
    status, body = post(api, session_path(sid, "reset"), {"options": [{"episode_idx": 0}]})
    assert (status, body["error"]["code"]) == (400, "bad_request")

    real_request = Worker.request

    async def buggy_request(
        self: Worker, command: str, shard_id: str, payload: Any, timeout_s: float
    ) -> worker_process.Reply:
        reply = await real_request(self, command, shard_id, payload, timeout_s)
        if command != "step":
            return reply
        # what worker_process.handle answers for a KeyError in env.step (tested above)
        trace = f'Traceback (most recent call last):\n  ...\nKeyError: "{SECRET}"'
        header = {"ok": False, "code": "internal_error", "parts": 0, "traceback": trace}
        return {**header, "message": worker_process.INTERNAL_FAILURE}, []

    monkeypatch.setattr(Worker, "request", buggy_request)
    with caplog.at_level("ERROR", logger="multion.api"):
        status, body = post(api, session_path(sid, "step"), {"actions": [1]})
    assert status == 500 and body["error"]["code"] == "internal_error"
    message = body["error"]["message"]
    assert "KeyError" not in message and "hunter2" not in message
    incident = message.split("incident ")[1].split(")")[0]
    assert f"incident {incident}" in caplog.text and SECRET in caplog.text
    monkeypatch.undo()
    # the session is still usable, as the worker kept its environments
    assert post(api, session_path(sid, "step"), {"actions": [1]})[0] == 200
    assert api.delete(session_path(sid)).status_code == 200
