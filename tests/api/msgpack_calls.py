"""Requests with msgpack bodies to an app under ``TestClient``, shared by the API tests."""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from multion_client.protocol import CONTENT_TYPE, decode, encode


def post(api: TestClient, path: str, body: Any) -> tuple[int, Any]:
    """POST ``body`` encoded as msgpack; the status and the decoded answer."""
    answer = api.post(path, content=encode(body), headers={"content-type": CONTENT_TYPE})
    return answer.status_code, decode(answer.content)
