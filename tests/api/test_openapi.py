"""The OpenAPI document describes the wire: every answer of a scripted tour of the API has a
documented status for its route and a body that its documented schema accepts, and request
bodies the server accepts conform to the documented request schemas."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from wire_schema import operation, problems, raw_decode

from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion_client.protocol import CONTENT_TYPE, encode, session_path


@pytest.fixture(scope="module")
def api() -> Iterator[TestClient]:
    settings = ServerSettings(workers=1, max_sessions=2, max_request_bytes=50_000)
    with TestClient(create_app(settings), raise_server_exceptions=False) as client:
        yield client


@pytest.fixture(scope="module")
def document(api: TestClient) -> dict[str, Any]:
    response = api.get("/openapi.json")
    assert response.status_code == 200
    return response.json()


class Tour:
    """Sends requests and checks each exchange against the document."""

    def __init__(self, api: TestClient, document: dict[str, Any]) -> None:
        self.api, self.document = api, document
        self.seen: set[tuple[str, str, int]] = set()

    def send(self, method: str, path: str, body: Any = None, raw: bytes | None = None) -> Any:
        spec = operation(self.document, method, path)
        content = raw if raw is not None else None if body is None else encode(body)
        response = self.api.request(
            method, path, content=content, headers={"content-type": CONTENT_TYPE}
        )
        status = str(response.status_code)
        assert status in spec["responses"], f"{method} {path} answered undocumented {status}"
        assert response.headers["content-type"] == CONTENT_TYPE
        schema = spec["responses"][status]["content"][CONTENT_TYPE]["schema"]
        answer = raw_decode(response.content)
        assert not problems(schema, answer), (method, path, status, problems(schema, answer))
        if body is not None and response.status_code < 300:
            request_schema = spec["requestBody"]["content"][CONTENT_TYPE]["schema"]
            assert not problems(request_schema, raw_decode(content)), (method, path, body)
        self.seen.add((method, spec["operationId"], response.status_code))
        return answer


def test_the_document_is_msgpack_only_with_real_status_codes(document: dict[str, Any]) -> None:
    assert "components" not in document or "HTTPValidationError" not in document["components"].get(
        "schemas", {}
    )
    for path, operations in document["paths"].items():
        for method, spec in operations.items():
            for status, answer in spec["responses"].items():
                assert list(answer["content"]) == [CONTENT_TYPE], (path, method, status)
            if "requestBody" in spec:
                schema = spec["requestBody"]["content"][CONTENT_TYPE]["schema"]
                assert schema["additionalProperties"] is False  # unknown fields are refused
    create = document["paths"]["/v1/sessions"]["post"]["responses"]
    assert "201" in create and "200" not in create
    assert "x-msgpack-ext: 1" in document["info"]["description"]


def test_every_answer_of_a_tour_conforms(
    api: TestClient, document: dict[str, Any], small_config: dict[str, Any]
) -> None:
    tour = Tour(api, document)
    tour.send("GET", "/v1/health")
    tour.send("GET", "/v1/spec")
    # create: good, bad config, malformed, too large, path not allowed, too many
    created = tour.send("POST", "/v1/sessions", {"config": small_config, "num_envs": 2})
    sid = created["session_id"]
    tour.send("POST", "/v1/sessions", {"config": {**small_config, "camera": {"width": 0}}})
    tour.send("POST", "/v1/sessions", {"confg": {}})
    tour.send("POST", "/v1/sessions", raw=b"\xc1")
    tour.send("POST", "/v1/sessions", raw=encode({"config": {"x": "y" * 60_000}}))
    tour.send("POST", "/v1/sessions", {"config": {"dataset": "/etc/passwd"}})
    other = tour.send("POST", "/v1/sessions", {"config": small_config})
    tour.send("POST", "/v1/sessions", {"config": small_config})  # 429: two sessions at most
    tour.send("DELETE", session_path(other["session_id"]))
    # observe before reset, step before reset
    tour.send("GET", session_path(sid, "observe"))
    tour.send("POST", session_path(sid, "step"), {"actions": [1, 1]})
    # reset: good, bad options, bad seeds, bad episode
    tour.send("POST", session_path(sid, "reset"), {"seeds": [0, 1]})
    tour.send("POST", session_path(sid, "reset"), {"options": [{"nope": 1}, None]})
    tour.send("POST", session_path(sid, "reset"), {"seeds": [-1, 0]})
    tour.send("POST", session_path(sid, "reset"), {"options": [{"episode_index": 99}, None]})
    tour.send("POST", session_path(sid, "reset"), {"seeds": [0, 1]})
    # step: good (list and array), illegal, wrong count, then an ended episode
    tour.send("POST", session_path(sid, "step"), {"actions": [1, 2]})
    tour.send("POST", session_path(sid, "step"), {"actions": np.array([3, 1])})
    tour.send("POST", session_path(sid, "step"), {"actions": [1, 7]})
    tour.send("POST", session_path(sid, "step"), {"actions": [1]})
    tour.send("GET", session_path(sid, "observe"))
    tour.send("POST", session_path(sid, "step"), {"actions": [0, 0]})  # wrong FOUNDs end both
    tour.send("POST", session_path(sid, "step"), {"actions": [1, 1]})  # 409
    tour.send("DELETE", session_path(sid))
    for method, verb, body in (
        ("POST", "reset", {}),
        ("POST", "step", {"actions": [1]}),
        ("GET", "observe", None),
        ("DELETE", None, None),
    ):
        tour.send(method, session_path(sid, verb), body)
    statuses = {status for _, _, status in tour.seen}
    assert {200, 201, 400, 403, 404, 409, 413, 422, 429} <= statuses
