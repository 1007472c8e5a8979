"""Request plumbing shared by the routers: the registry, bounded msgpack bodies, responses."""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Annotated, Any

from fastapi import Depends, Request
from fastapi.responses import Response

from multion.api.sessions import SessionRegistry
from multion.api.settings import ServerSettings
from multion_client.errors import MalformedMessage, RequestTooLarge, SessionsNotAllowed
from multion_client.protocol import CONTENT_TYPE, decode, encode

Authenticate = Callable[[Request], Awaitable[int]]
"""The team id of a request's bearer token (401 without a valid one): the leaderboard's."""


class MsgpackResponse(Response):
    """A response whose body is msgpack (already-encoded bytes are sent as they are)."""

    media_type = CONTENT_TYPE

    def render(self, content: Any) -> bytes | memoryview:
        if isinstance(content, (bytes, memoryview)):
            return content
        return encode(content)


def registry_of(request: Request) -> SessionRegistry:
    registry: SessionRegistry = request.app.state.registry
    return registry


# Dependencies are coroutines: FastAPI would run plain functions in a thread pool per request.
async def get_registry(request: Request) -> SessionRegistry:
    return registry_of(request)


async def get_settings(request: Request) -> ServerSettings:
    settings: ServerSettings = request.app.state.settings
    return settings


async def session_owner(request: Request) -> str:
    """Who opens a plain session, by the server's ``sessions`` mode: its team (token), else its
    IP address (open); 403 when plain sessions are off."""
    settings: ServerSettings = request.app.state.settings
    if settings.sessions == "off":
        raise SessionsNotAllowed(
            "this server serves leaderboard runs only: plain sessions are off (--sessions off)"
        )
    if settings.sessions == "token":
        authenticate: Authenticate = request.app.state.authenticate
        return f"team:{await authenticate(request)}"
    return f"ip:{request.client.host if request.client else 'unknown'}"


async def read_message(request: Request) -> Any:
    """The decoded msgpack body; 413 above ``max_request_bytes``, 400 if it is not msgpack."""
    limit = request.app.state.settings.max_request_bytes
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise RequestTooLarge(f"request body of {declared} bytes is over the {limit}-byte limit")
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise RequestTooLarge(f"request body is over the {limit}-byte limit")
        chunks.append(chunk)
    if size == 0:
        raise MalformedMessage("the request needs a msgpack body")
    return decode(b"".join(chunks))


Registry = Annotated[SessionRegistry, Depends(get_registry)]
Settings = Annotated[ServerSettings, Depends(get_settings)]
Message = Annotated[Any, Depends(read_message)]
