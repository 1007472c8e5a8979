"""The FastAPI application: routers, error handlers and the worker pool's lifespan."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import secrets
from collections.abc import AsyncIterator, Sequence
from contextlib import AbstractAsyncContextManager
from typing import Protocol

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException

from multion.api.deps import MsgpackResponse
from multion.api.openapi import install_openapi
from multion.api.routers import icon, live, meta, sessions
from multion.api.sessions import SessionRegistry
from multion.api.settings import ServerSettings, fit_outer_memory_limit
from multion.api.step_fast_path import StepFastPath
from multion.api.workers import WorkerPool
from multion.config.ranges import ConfigError
from multion_client.errors import (
    BadRequest,
    InternalError,
    MethodNotAllowed,
    MultiONError,
    NotFound,
    error_from_code,
)
from multion_client.protocol import API_VERSION

log = logging.getLogger("multion.api")

DESCRIPTION = """\
Remote MultiON environments. Create a session (one or more environments), then reset and step
it; observations come back as msgpack with numpy arrays as raw bytes. Metrics are computed here;
clients only send actions. The `multion_client` package (`Client`, `RemoteEnv`,
`RemoteVectorEnv`) speaks this protocol."""


class AppExtension(Protocol):
    """A service the app serves beside the sessions, such as the leaderboard
    (``multion.leaderboard.app.LeaderboardExtension``): passed in by whoever composes the
    server, so that this layer never imports the ones above it."""

    authenticates_teams: bool
    """It sets ``app.state.authenticate`` (team tokens), which ``sessions = 'token'`` needs."""

    def install(self, app: FastAPI) -> None:
        """Check its inputs (raising on bad ones) and add its routes, as the app is built."""

    def lifespan(
        self, app: FastAPI, registry: SessionRegistry
    ) -> AbstractAsyncContextManager[None]:
        """What runs while the app serves, inside the worker pool's lifespan."""


def create_app(
    settings: ServerSettings | None = None, extensions: Sequence[AppExtension] = ()
) -> FastAPI:
    """A MultiON server app; its lifespan starts and stops the simulator workers.

    ``extensions`` are served beside the sessions (the leaderboard's run routes and pages);
    without any the app is a plain session server.
    """
    settings, warning = fit_outer_memory_limit(settings or ServerSettings())
    if warning:  # `multion serve` fitted them already; an app built another way says it here
        log.warning(warning)
    if settings.sessions == "token" and not any(e.authenticates_teams for e in extensions):
        raise ConfigError(
            "sessions = 'token' needs a challenge (--challenge FILE): team tokens come from "
            "the leaderboard"
        )

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        pool = WorkerPool(
            settings.workers, settings.worker_start_timeout_s, settings.worker_memory_mb * 2**20
        )
        try:
            await pool.start()
        except BaseException:
            await pool.stop()
            raise
        registry = SessionRegistry(settings, pool)
        app.state.settings, app.state.registry = settings, registry
        reaper = asyncio.create_task(registry.reap_forever())
        try:
            async with contextlib.AsyncExitStack() as running:
                for extension in extensions:
                    await running.enter_async_context(extension.lifespan(app, registry))
                yield
        finally:
            reaper.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await reaper
            await pool.stop()  # workers close their environments as they exit

    app = FastAPI(
        title="MultiON server",
        version=API_VERSION,
        description=DESCRIPTION,
        lifespan=lifespan,
    )
    install_openapi(app)
    app.include_router(meta.router)
    app.include_router(sessions.router)
    app.include_router(live.router)
    app.include_router(icon.router)
    for extension in extensions:
        extension.install(app)
    app.add_middleware(StepFastPath)
    app.add_exception_handler(MultiONError, _api_error)
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(HTTPException, _http_error)
    app.add_exception_handler(Exception, _unexpected_error)
    return app


def _respond(error: MultiONError) -> MsgpackResponse:
    return MsgpackResponse(error.to_wire(), status_code=error.status)


async def _api_error(request: Request, error: Exception) -> MsgpackResponse:
    assert isinstance(error, MultiONError)
    return _respond(error)


async def _validation_error(request: Request, error: Exception) -> MsgpackResponse:
    assert isinstance(error, RequestValidationError)
    problems = "; ".join(
        f"{'.'.join(str(p) for p in e.get('loc', ()))}: {e.get('msg')}" for e in error.errors()
    )
    return _respond(BadRequest(f"invalid request: {problems}", status=422))


async def _http_error(request: Request, error: Exception) -> MsgpackResponse:
    assert isinstance(error, HTTPException)
    if error.status_code == 404:
        wrapped: MultiONError = NotFound(f"no route {request.method} {request.url.path}")
    elif error.status_code == 405:
        wrapped = MethodNotAllowed(f"{request.method} is not allowed on {request.url.path}")
    else:
        wrapped = error_from_code(f"http_{error.status_code}", str(error.detail), error.status_code)
    return _respond(wrapped)


async def _unexpected_error(request: Request, error: Exception) -> MsgpackResponse:
    # The exception's text stays in the log (it can name files, queries, internals); the
    # client gets an incident number to quote.
    incident = secrets.token_hex(4)
    log.error("incident %s: unexpected error in %s %s", incident, request.method,
              request.url.path, exc_info=error)  # fmt: skip
    return _respond(
        InternalError(f"the server failed on this request (incident {incident}); retry later")
    )
