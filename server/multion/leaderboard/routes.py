"""The run routes (``/v1/runs``) and the public challenge description (``/v1/challenge``).

Every run route needs ``Authorization: Bearer <token>``; a team sees only its own runs
(another team's run answers 404, as if it did not exist).
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Coroutine
from typing import Any, TypeVar

from fastapi import APIRouter, Request

from multion.api.deps import MsgpackResponse, read_message
from multion.leaderboard.runs import RunService
from multion.leaderboard.storage import team_for_token
from multion_client import errors
from multion_client.protocol import (
    CHALLENGE_PATH,
    RUNS_PATH,
    CreateRun,
    RunList,
    RunStep,
    StartEpisode,
)

T = TypeVar("T")
router = APIRouter(tags=["leaderboard"], default_response_class=MsgpackResponse)

_MSGPACK = "application/x-msgpack"


def _answers(ok: str, *codes: int) -> dict[int | str, dict[str, Any]]:
    text = {
        400: "malformed body or illegal action",
        401: "missing, unknown or revoked token",
        403: "a seed, reset options, an episode choice or a sensor the track does not allow",
        404: "no such run for this team, or no such track / phase",
        409: "episode in progress, wrong sequence number, or the run is over",
        413: "request body over the server's limit",
        422: "invalid map options",
        429: "the team's quota for this phase is used up",
        503: "the simulator failed: the run is over and refunded",
    }
    error = {"content": {_MSGPACK: {}}, "description": "{'error': {'code', 'message'}}"}
    answers: dict[int | str, dict[str, Any]] = {200: {"content": {_MSGPACK: {}}, "description": ok}}
    for code in codes:
        answers[code] = {**error, "description": text[code]}
    return answers


async def unabandoned(operation: Coroutine[Any, Any, T]) -> T:
    """Await ``operation`` in its own task: a client hanging up mid-step must not cancel it
    between the simulator step and the saved state (a retry would then act twice)."""
    task = asyncio.ensure_future(operation)
    task.add_done_callback(lambda t: t.cancelled() or t.exception())
    return await asyncio.shield(task)


def _service(request: Request) -> RunService:
    service = getattr(request.app.state, "runs", None)
    if service is None:
        raise errors.UnknownTrack(
            "this server runs no challenge (start it with `multion serve --challenge FILE`)"
        )
    return service


class TokenCache:
    """Checked tokens, trusted for ``ttl_s`` seconds so a step costs no database read."""

    def __init__(self, ttl_s: float) -> None:
        self.ttl_s = ttl_s
        self._known: dict[str, tuple[int, float]] = {}

    def get(self, token: str) -> int | None:
        hit = self._known.get(token)
        if hit is None or hit[1] < time.monotonic():
            return None
        return hit[0]

    def put(self, token: str, team_id: int) -> None:
        if self.ttl_s > 0:
            if len(self._known) > 10_000:
                self._known.clear()
            self._known[token] = (team_id, time.monotonic() + self.ttl_s)


async def team_of(request: Request) -> int:
    """The id of the calling team; 401 without a valid bearer token."""
    service = _service(request)
    header = request.headers.get("authorization", "")
    scheme, _, token = header.partition(" ")
    if scheme.lower() != "bearer" or not token.strip():
        raise errors.Unauthorized(
            "this route needs 'Authorization: Bearer <token>' (the organisers give each team "
            "a token: `multion leaderboard team add NAME`)"
        )
    token = token.strip()
    cache: TokenCache = request.app.state.token_cache
    team_id = cache.get(token)
    if team_id is None:

        def check() -> int | None:
            with service.db.sessions() as session:
                team = team_for_token(session, token)
                return None if team is None else team.id

        team_id = await asyncio.to_thread(check)
        if team_id is None:
            raise errors.Unauthorized("unknown or revoked token")
        cache.put(token, team_id)
    return team_id


@router.get(
    CHALLENGE_PATH,
    summary="The challenge",
    description="Tracks (task, allowed sensors, camera, ranking metric), their phases (episodes, "
    "feedback, quotas, sealing date) and the time limits of a run. Needs no token.",
    responses=_answers("msgpack map", 404),
)
async def challenge(request: Request) -> MsgpackResponse:
    return MsgpackResponse(_service(request).challenge.describe())


@router.post(
    RUNS_PATH,
    status_code=201,
    summary="Create a run",
    description="Start a run of a track's phase (CreateRun: track, phase, method, optional "
    "sensors, maps, paper_url, code_url). The quota is debited now: an abandoned run counts; "
    "a run the server breaks is refunded.",
    responses=_answers("RunInfo", 400, 401, 403, 404, 413, 422, 429, 503),
)
async def create_run(request: Request) -> MsgpackResponse:
    team_id = await team_of(request)
    message = CreateRun.from_wire(await read_message(request))
    info = await unabandoned(_service(request).create(team_id, message))
    return MsgpackResponse(info.to_wire(), status_code=201)


@router.get(
    RUNS_PATH,
    summary="The team's runs",
    responses=_answers("RunList, newest first", 401),
)
async def list_runs(request: Request) -> MsgpackResponse:
    team_id = await team_of(request)
    runs = await _service(request).list_runs(team_id)
    return MsgpackResponse(RunList(runs).to_wire())


@router.get(
    RUNS_PATH + "/{run_id}",
    summary="A run's state",
    description="RunStatus: state (running, finished, ended, failed), progress, why it ended, "
    "and the results its phase shows (per-episode on minival, aggregates on test-standard, "
    "nothing on test-challenge until its sealing date).",
    responses=_answers("RunStatus", 401, 404),
)
async def run_status(run_id: str, request: Request) -> MsgpackResponse:
    team_id = await team_of(request)
    return MsgpackResponse((await _service(request).status(team_id, run_id)).to_wire())


@router.post(
    RUNS_PATH + "/{run_id}/episodes",
    summary="Start the run's next episode",
    description="StartEpisode `{episode: n}`: n must be the next episode, after the current "
    "one ended; n of the episode already started returns its observation again. No seeds, no "
    "options.",
    responses=_answers("RunObservation", 400, 401, 403, 404, 409, 503),
)
async def start_episode(run_id: str, request: Request) -> MsgpackResponse:
    team_id = await team_of(request)
    message = StartEpisode.from_wire(await read_message(request))
    return MsgpackResponse(
        await unabandoned(_service(request).start_episode(team_id, run_id, message))
    )


@router.post(
    RUNS_PATH + "/{run_id}/step",
    summary="One action of the current episode",
    description="RunStep `{episode, seq, action}`: seq counts the episode's actions from 1. "
    "The last (episode, seq) sent again returns the same answer without acting twice.",
    responses=_answers("RunObservation", 400, 401, 403, 404, 409, 413, 503),
)
async def step(run_id: str, request: Request) -> MsgpackResponse:
    team_id = await team_of(request)
    message = RunStep.from_wire(await read_message(request))
    service = _service(request)
    body = await unabandoned(
        service.step(team_id, run_id, message.episode, message.seq, message.action)
    )
    return MsgpackResponse(body)


@router.get(
    RUNS_PATH + "/{run_id}/observe",
    summary="Where the run stands",
    description="The answer to the last start or step of the current episode (to resume after "
    "a client crash); `done` with an empty observation between episodes.",
    responses=_answers("RunObservation", 401, 404, 409),
)
async def observe(run_id: str, request: Request) -> MsgpackResponse:
    team_id = await team_of(request)
    return MsgpackResponse(await _service(request).observe(team_id, run_id))


@router.delete(
    RUNS_PATH + "/{run_id}",
    summary="Abandon a run",
    description="End the run now: its missing episodes count as failures; the quota stays used.",
    responses=_answers("RunStatus", 401, 404, 409),
)
async def abandon(run_id: str, request: Request) -> MsgpackResponse:
    team_id = await team_of(request)
    return MsgpackResponse(
        (await unabandoned(_service(request).abandon(team_id, run_id))).to_wire()
    )
