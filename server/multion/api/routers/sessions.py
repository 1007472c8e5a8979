"""The session routes: create, reset, step, observe, close (bodies are msgpack)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request

from multion.api.deps import Message, MsgpackResponse, Registry, read_message, registry_of
from multion_client.protocol import SESSIONS_PATH, CreateSession, Reset, Step

router = APIRouter(prefix=SESSIONS_PATH, tags=["sessions"], default_response_class=MsgpackResponse)

_MSGPACK = "application/x-msgpack"


def _body(description: str, schema: dict[str, Any]) -> dict[str, Any]:
    """OpenAPI text for a msgpack request body (the schema describes the decoded map)."""
    return {
        "requestBody": {
            "required": True,
            "description": description,
            "content": {_MSGPACK: {"schema": {"type": "object", **schema}}},
        }
    }


def _answers(ok: str, *codes: int) -> dict[int | str, dict[str, Any]]:
    text = {
        400: "malformed msgpack, wrong fields, wrong number of actions, illegal action",
        404: "unknown session (never created, closed or reaped when idle)",
        409: "the episode is over (no auto-reset) or has not started: reset first",
        413: "request body over the server's limit",
        422: "invalid config or episode",
        429: "too many sessions or environments",
        503: "the simulator worker of this session died; the session is lost",
    }
    error = {"content": {_MSGPACK: {}}, "description": "{'error': {'code', 'message'}}"}
    answers: dict[int | str, dict[str, Any]] = {200: {"content": {_MSGPACK: {}}, "description": ok}}
    for code in codes:
        answers[code] = {**error, "description": text[code]}
    return answers


# reset / step / observe are the per-step hot path: they read the body and the registry
# directly, because FastAPI's dependency solving costs a noticeable share of a small request.

_OBSERVATIONS = (
    "msgpack map `{observations: [per-env map of arrays], infos: [per-env map]}`; arrays are "
    "msgpack extension 1 (dtype, shape, raw bytes), see `multion_client.protocol`"
)


@router.post(
    "",
    status_code=201,
    summary="Create a session",
    description="Start `num_envs` environments configured by `config` (an EnvConfig as nested "
    "maps, unknown fields are rejected; `episodes` may list Episode maps to play). With "
    "`auto_reset`, an environment whose episode ends is reset in the same step (Gymnasium "
    "SAME_STEP: `infos[i].final_obs` / `final_info` hold the ended episode's last outputs). "
    "The environments may be spread over several simulator workers.",
    openapi_extra=_body(
        "CreateSession",
        {
            "properties": {
                "config": {"type": "object"},
                "num_envs": {"type": "integer", "minimum": 1, "default": 1},
                "auto_reset": {"type": "boolean", "default": False},
            }
        },
    ),
    responses=_answers(
        "SessionInfo: session_id, num_envs, auto_reset, spaces", 400, 413, 422, 429, 503
    ),
)
async def create_session(message: Message, registry: Registry) -> MsgpackResponse:
    body = await registry.create(CreateSession.from_wire(message))
    return MsgpackResponse(body, status_code=201)


@router.post(
    "/{session_id}/reset",
    summary="Reset every environment of a session",
    description="Start new episodes. `seeds` and `options` have one entry per environment "
    "(nil for none; empty lists mean none at all). Options: `episode_index`, `episode_id` or "
    "`episode` (an Episode map).",
    openapi_extra=_body(
        "Reset",
        {
            "properties": {
                "seeds": {"type": "array", "items": {"type": ["integer", "null"]}},
                "options": {"type": "array", "items": {"type": ["object", "null"]}},
            }
        },
    ),
    responses=_answers(_OBSERVATIONS, 400, 404, 413, 422, 503),
)
async def reset(session_id: str, request: Request) -> MsgpackResponse:
    message = Reset.from_wire(await read_message(request))
    return MsgpackResponse(await registry_of(request).reset(session_id, message))


@router.post(
    "/{session_id}/step",
    summary="Step every environment of a session",
    description="`actions` holds exactly one action per environment (0 FOUND, 1 MOVE_FORWARD, "
    "2 TURN_LEFT, 3 TURN_RIGHT). All environments step in this one request.",
    openapi_extra=_body(
        "Step",
        {
            "required": ["actions"],
            "properties": {
                "actions": {
                    "type": "array",
                    "items": {"type": "integer", "minimum": 0, "maximum": 3},
                }
            },
        },
    ),
    responses=_answers(
        "StepResult: `{observations, rewards, terminated, truncated, infos}`, one entry per env",
        400,
        404,
        409,
        413,
        503,
    ),
)
async def step(session_id: str, request: Request) -> MsgpackResponse:
    message = Step.from_wire(await read_message(request))
    return MsgpackResponse(await registry_of(request).step(session_id, message))


@router.get(
    "/{session_id}/observe",
    summary="Latest observations of a session",
    description="The observations and infos of the last reset or step, without acting.",
    responses=_answers(_OBSERVATIONS, 404, 409, 503),
)
async def observe(session_id: str, request: Request) -> MsgpackResponse:
    return MsgpackResponse(await registry_of(request).observe(session_id))


@router.delete(
    "/{session_id}",
    summary="Close a session",
    description="Free the session's environments. Works for a session whose worker died.",
    responses=_answers("`{closed: session_id}`", 404),
)
async def close_session(session_id: str, registry: Registry) -> MsgpackResponse:
    await registry.close(session_id)
    return MsgpackResponse({"closed": session_id})
