"""The session routes: create, reset, step, observe, close (bodies are msgpack)."""

from __future__ import annotations

from fastapi import APIRouter, Request

from multion.api.deps import (
    Message,
    MsgpackResponse,
    Registry,
    read_message,
    registry_of,
    session_owner,
)
from multion.api.openapi import answers, request_body
from multion_client import errors as e
from multion_client.protocol import (
    RENDERER_HEADER,
    SESSIONS_PATH,
    CreateSession,
    Observations,
    Reset,
    SessionClosed,
    SessionInfo,
    Step,
    StepResult,
)

router = APIRouter(prefix=SESSIONS_PATH, tags=["sessions"], default_response_class=MsgpackResponse)

# reset / step / observe are the per-step hot path: they read the body and the registry
# directly, because FastAPI's dependency solving costs a noticeable share of a small request.

# Errors every route with a body can answer with, and those of a session that is gone.
BODY_ERRORS = (e.MalformedMessage, e.RequestTooLarge)
SESSION_ERRORS = (e.SessionNotFound, e.WorkerFailed)


@router.post(
    "",
    status_code=201,
    summary="Create a session",
    description="Start `num_envs` environments configured by `config` (an EnvConfig as nested "
    "maps, unknown fields are rejected; `episodes` may list Episode maps to play). With "
    "`auto_reset`, an environment whose episode ends is reset in the same step (Gymnasium "
    "SAME_STEP: `infos[i].final_obs` / `final_info` hold the ended episode's last outputs). "
    "The environments may be spread over several simulator workers. A server may need a team "
    "token for this (`--sessions token`), refuse it (`--sessions off`), and caps the sessions "
    "one client holds. The `multion-renderer` header names what the environments render with "
    "(`gl` or `tiny`: `camera.renderer` with `auto` resolved).",
    openapi_extra=request_body(CreateSession),
    responses=answers(
        201,
        SessionInfo,
        *BODY_ERRORS,
        e.Unauthorized,
        e.SessionsNotAllowed,
        e.PathNotAllowed,
        e.InvalidConfig,
        e.TooManySessions,
        e.TooManyEnvs,
        e.MemoryBudgetExceeded,
        e.WorkerFailed,
    ),
)
async def create_session(message: Message, registry: Registry, request: Request) -> MsgpackResponse:
    owner = await session_owner(request)
    session = await registry.create(CreateSession.from_wire(message), owner=owner)
    headers = {RENDERER_HEADER: session.renderer} if session.renderer else None
    return MsgpackResponse(session.info, status_code=201, headers=headers)


@router.post(
    "/{session_id}/reset",
    summary="Reset every environment of a session",
    description="Start new episodes. `seeds` and `options` have one entry per environment "
    "(nil for none; empty lists mean none at all). Options: `episode_index`, `episode_id` or "
    "`episode` (an Episode map).",
    openapi_extra=request_body(Reset),
    responses=answers(
        200,
        Observations,
        *BODY_ERRORS,
        e.BadRequest,
        e.PathNotAllowed,
        e.InvalidEpisode,
        *SESSION_ERRORS,
    ),  # fmt: skip
)
async def reset(session_id: str, request: Request) -> MsgpackResponse:
    message = Reset.from_wire(await read_message(request))
    return MsgpackResponse(await registry_of(request).reset(session_id, message))


@router.post(
    "/{session_id}/step",
    summary="Step every environment of a session",
    description="`actions` holds exactly one action per environment (0 FOUND, 1 MOVE_FORWARD, "
    "2 TURN_LEFT, 3 TURN_RIGHT). All environments step in this one request.",
    openapi_extra=request_body(Step),
    responses=answers(
        200,
        StepResult,
        *BODY_ERRORS,
        e.BadRequest,
        e.InvalidAction,
        e.EpisodeOver,
        *SESSION_ERRORS,
    ),  # fmt: skip
)
async def step(session_id: str, request: Request) -> MsgpackResponse:
    message = Step.from_wire(await read_message(request))
    return MsgpackResponse(await registry_of(request).step(session_id, message))


@router.get(
    "/{session_id}/observe",
    summary="Latest observations of a session",
    description="The observations and infos of the last reset or step, without acting.",
    responses=answers(200, Observations, e.NotReset, *SESSION_ERRORS),
)
async def observe(session_id: str, request: Request) -> MsgpackResponse:
    return MsgpackResponse(await registry_of(request).observe(session_id))


@router.delete(
    "/{session_id}",
    summary="Close a session",
    description="Free the session's environments. Works for a session whose worker died.",
    responses=answers(200, SessionClosed, e.SessionNotFound),
)
async def close_session(session_id: str, registry: Registry) -> MsgpackResponse:
    await registry.close(session_id)
    return MsgpackResponse(SessionClosed(session_id).to_wire())
