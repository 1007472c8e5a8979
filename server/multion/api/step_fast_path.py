"""``POST /v1/sessions/{id}/step`` without FastAPI's routing, dependencies and inner middleware.

Every request through FastAPI costs this server ~0.4 ms of CPU before any work (a 404 does, on
the 2-core reference machine); with the ``gl`` renderer a step costs the simulator ~4 ms at
256², so the framework's share showed (``multion bench --only http``). This middleware answers
the one route that agents call hundreds of times a second by calling the routed endpoint
(``routers.sessions.step``) itself, and turns its typed errors into the same msgpack answers as
the app's handler. Any other request goes on to the app, and unexpected errors propagate to
the app's outermost handler, as they would from the route.
"""

from __future__ import annotations

import re

from starlette.requests import Request
from starlette.types import ASGIApp, Receive, Scope, Send

from multion.api.deps import MsgpackResponse
from multion.api.routers.sessions import step
from multion_client.errors import MultiONError
from multion_client.protocol import SESSIONS_PATH

STEP_PATH = re.compile(re.escape(SESSIONS_PATH) + r"/([^/]+)/step")


class StepFastPath:
    """ASGI middleware (``app.add_middleware(StepFastPath)``)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        match = STEP_PATH.fullmatch(scope["path"]) if scope["type"] == "http" else None
        if match is None or scope["method"] != "POST":
            await self.app(scope, receive, send)
            return
        try:
            response = await step(match.group(1), Request(scope, receive))
        except MultiONError as error:
            response = MsgpackResponse(error.to_wire(), status_code=error.status)
        await response(scope, receive, send)
