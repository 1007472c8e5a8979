"""Replica names (``--replica NAME`` / ``MULTION_REPLICA``): session and run ids start with
``NAME-`` (≤ 32 characters) so that a reverse proxy can route by them; without it ids are 32 hex
digits as before."""

from __future__ import annotations

import re
import uuid
from typing import Any

import pytest
from fastapi.testclient import TestClient
from pydantic import ValidationError

from multion.api import cli_serve
from multion.api.app import create_app
from multion.api.settings import ID_LENGTH, ServerSettings, replica_of
from multion_client.protocol import CONTENT_TYPE, decode, encode, session_path


def test_without_a_replica_ids_are_uuid4_hex() -> None:
    ids = {ServerSettings().new_id() for _ in range(100)}
    assert len(ids) == 100
    for some_id in ids:
        assert re.fullmatch(r"[0-9a-f]{32}", some_id)
        assert uuid.UUID(hex=some_id).version == 4
        assert replica_of(some_id) is None


@pytest.mark.parametrize("name", ["a", "r2", "abcdefgh", "0"])
def test_a_replica_prefixes_ids_within_32_characters(name: str) -> None:
    settings = ServerSettings(replica=name)
    ids = {settings.new_id() for _ in range(100)}
    assert len(ids) == 100
    for some_id in ids:
        assert len(some_id) == ID_LENGTH
        assert re.fullmatch(rf"{name}-[0-9a-f]+", some_id), some_id
        assert replica_of(some_id) == name


def test_id_length_fits_the_run_table() -> None:
    from multion.leaderboard.models import Run

    assert Run.__table__.c.id.type.length == ID_LENGTH


@pytest.mark.parametrize("name", ["A", "abcdefghi", "a-b", "a_b", " a", "é", "a\n"])
def test_a_bad_replica_name_is_refused(name: str) -> None:
    with pytest.raises(ValidationError) as raised:
        ServerSettings(replica=name)
    (error,) = raised.value.errors()
    assert error["loc"] == ("replica",)
    assert "1-8 characters from a-z and 0-9" in error["msg"] and repr(name) in error["msg"]


def test_replica_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MULTION_REPLICA", "east1")
    assert ServerSettings().replica == "east1"
    monkeypatch.setenv("MULTION_REPLICA", "")  # empty: no name
    assert ServerSettings().replica is None
    monkeypatch.setenv("MULTION_REPLICA", "East-1")
    with pytest.raises(ValidationError, match="replica"):
        ServerSettings()


def test_serve_refuses_a_bad_replica_name(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_serve.main(["--replica", "Bad!"]) == 2
    out = capsys.readouterr().out
    assert "replica" in out and "1-8 characters from a-z and 0-9" in out


def test_sessions_of_a_named_replica(small_config: dict[str, Any]) -> None:
    settings = ServerSettings(workers=1, replica="r7")
    with TestClient(create_app(settings), raise_server_exceptions=False) as api:

        def call(method: str, path: str, body: Any = None) -> tuple[int, Any]:
            content = None if body is None else encode(body)
            headers = {"content-type": CONTENT_TYPE}
            response = api.request(method, path, content=content, headers=headers)
            return response.status_code, decode(response.content)

        status, info = call("POST", "/v1/sessions", {"config": small_config, "num_envs": 1})
        assert status == 201, info
        session_id = info["session_id"]
        assert re.fullmatch(r"r7-[0-9a-f]{29}", session_id), session_id
        assert call("POST", session_path(session_id, "reset"), {"seeds": [1]})[0] == 200
        assert call("POST", session_path(session_id, "step"), {"actions": [1]})[0] == 200
        # a session another replica made: the 404 says where it lives
        status, body = call("GET", session_path("r8-" + session_id[3:], "observe"))
        assert status == 404 and body["error"]["code"] == "session_not_found"
        assert "replica 'r8' made it" in body["error"]["message"]
        # an id without a replica name: the usual message
        status, body = call("GET", session_path("0" * 32, "observe"))
        assert status == 404 and "never created" in body["error"]["message"]
        assert call("DELETE", session_path(session_id))[0] == 200
