"""The OpenAPI document, true to the wire: msgpack bodies described by the protocol's schemas.

Request and answer bodies come from the message dataclasses of ``multion_client.protocol``
(through ``multion_client.schema``), error answers list the codes each route can send with its
status, and FastAPI's JSON validation answers, which this server never sends, are left out.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi

from multion_client.errors import MultiONError
from multion_client.protocol import CONTENT_TYPE
from multion_client.schema import EXTENSION_KEYWORD, NDARRAY, error_schema, message_schema

WIRE = f"""

## The wire
Bodies are msgpack (`{CONTENT_TYPE}`); the schemas below describe the decoded maps. numpy
arrays are not JSON: where a schema says `{EXTENSION_KEYWORD}: 1` the value is msgpack extension
1, {NDARRAY["description"].removeprefix("a numpy array as msgpack extension 1: ")};
`{EXTENSION_KEYWORD}: 2` is a numpy scalar in the same layout. Every error answer is
`{{"error": {{"code", "message"}}}}`, with the codes listed per route and status.
"""


def request_body(message: type) -> dict[str, Any]:
    """``openapi_extra`` for a route whose msgpack body is ``message``."""
    return {
        "requestBody": {
            "required": True,
            "content": {CONTENT_TYPE: {"schema": message_schema(message)}},
        }
    }


def answers(
    ok_status: int, ok: type, *failures: type[MultiONError]
) -> dict[int | str, dict[str, Any]]:
    """``responses`` for a route: its success body and the errors it can answer with."""
    documented: dict[int | str, dict[str, Any]] = {
        ok_status: {
            "description": _summary(ok),
            "content": {CONTENT_TYPE: {"schema": message_schema(ok)}},
        }
    }
    by_status: dict[int, list[type[MultiONError]]] = {}
    for error in failures:
        by_status.setdefault(error.status, []).append(error)
    for status, errors in sorted(by_status.items()):
        documented[status] = {
            "description": "; ".join(f"`{e.code}`: {_summary(e)}" for e in errors),
            "content": {CONTENT_TYPE: {"schema": error_schema([e.code for e in errors])}},
        }
    return documented


def install_openapi(app: FastAPI) -> None:
    """Make ``app.openapi()`` (and ``/openapi.json``) return :func:`openapi_document`."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            app.openapi_schema = openapi_document(app)
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]  # FastAPI's documented way to extend


def openapi_document(app: FastAPI) -> dict[str, Any]:
    document = get_openapi(
        title=app.title,
        version=app.version,
        description=app.description + WIRE,
        routes=app.routes,
    )
    for operations in document["paths"].values():
        for operation in operations.values():
            answers = operation["responses"]
            if "422" in answers and "application/json" in answers["422"].get("content", {}):
                del answers["422"]  # FastAPI's parameter validation: never sent here
    schemas = document.get("components", {}).get("schemas", {})
    for name in ("HTTPValidationError", "ValidationError"):
        schemas.pop(name, None)
    if "components" in document and not schemas:
        document["components"].pop("schemas", None)
        if not document["components"]:
            del document["components"]
    return document


def _summary(documented: type | Callable[..., Any]) -> str:
    return " ".join((documented.__doc__ or "").strip().split("\n\n")[0].split())
