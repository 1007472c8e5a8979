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
from multion.api.openapi import answers, request_body
from multion.leaderboard.runs import RunService
from multion.leaderboard.storage import team_for_token
from multion_client import errors
from multion_client import errors as e
from multion_client.run_protocol import (
    CHALLENGE_PATH,
    RUNS_PATH,
    ChallengeInfo,
    CreateRun,
    RunInfo,
    RunList,
    RunObservation,
    RunStatus,
    RunStep,
    StartEpisode,
)

BODY_ERRORS = (e.MalformedMessage, e.RequestTooLarge)
RUN_ERRORS = (e.Unauthorized, e.RunNotFound, e.UnknownTrack)
PLAY_ERRORS = (e.EpisodeInProgress, e.SequenceMismatch, e.EpisodeOver, e.RunOver, e.WorkerFailed)

T = TypeVar("T")
router = APIRouter(tags=["leaderboard"], default_response_class=MsgpackResponse)


async def unabandoned(operation: Coroutine[Any, Any, T]) -> T:
    """Await ``operation`` in its own task: a client hanging up mid-step must not cancel it
    between the simulator step and the saved state (a retry would then act twice)."""
    task = asyncio.ensure_future(operation)
    task.add_done_callback(lambda t: t.cancelled() or t.exception())
    return await asyncio.shield(task)


def _service(request: Request) -> RunService:
    service: RunService | None = getattr(request.app.state, "runs", None)
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
    responses=answers(200, ChallengeInfo, e.UnknownTrack),
)
async def challenge(request: Request) -> MsgpackResponse:
    return MsgpackResponse(ChallengeInfo(**_service(request).challenge.describe()).to_wire())


@router.post(
    RUNS_PATH,
    status_code=201,
    summary="Create a run",
    description="Start a run of a track's phase (CreateRun: track, phase, method, optional "
    "sensors, maps, paper_url, code_url). The quota is debited now: an abandoned run counts; "
    "a run the server breaks is refunded.",
    openapi_extra=request_body(CreateRun),
    responses=answers(
        201,
        RunInfo,
        *BODY_ERRORS,
        *RUN_ERRORS,
        e.NotAllowedInRun,
        e.InvalidConfig,
        e.QuotaExceeded,
        e.TooManySessions,
        e.MemoryBudgetExceeded,
        e.WorkerFailed,
    ),  # fmt: skip
)
async def create_run(request: Request) -> MsgpackResponse:
    team_id = await team_of(request)
    message = CreateRun.from_wire(await read_message(request))
    info = await unabandoned(_service(request).create(team_id, message))
    return MsgpackResponse(info.to_wire(), status_code=201)


@router.get(
    RUNS_PATH,
    summary="The team's runs",
    responses=answers(200, RunList, e.Unauthorized, e.UnknownTrack),
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
    responses=answers(200, RunStatus, *RUN_ERRORS),
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
    openapi_extra=request_body(StartEpisode),
    responses=answers(
        200, RunObservation, *BODY_ERRORS, *RUN_ERRORS, e.NotAllowedInRun, *PLAY_ERRORS
    ),
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
    openapi_extra=request_body(RunStep),
    responses=answers(
        200,
        RunObservation,
        *BODY_ERRORS,
        *RUN_ERRORS,
        e.NotAllowedInRun,
        e.InvalidAction,
        *PLAY_ERRORS,
    ),  # fmt: skip
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
    description="The answer to the last start or step of a lane's current episode (to resume "
    "after a client crash); `done` with an empty observation between episodes. `lane` "
    "(default 0) for runs that play several episodes at once.",
    responses=answers(200, RunObservation, *RUN_ERRORS, e.BadRequest, e.RunOver, e.WorkerFailed),
)
async def observe(run_id: str, request: Request, lane: int = 0) -> MsgpackResponse:
    team_id = await team_of(request)
    return MsgpackResponse(await _service(request).observe(team_id, run_id, lane))


@router.delete(
    RUNS_PATH + "/{run_id}",
    summary="Abandon a run",
    description="End the run now: its missing episodes count as failures; the quota stays used.",
    responses=answers(200, RunStatus, *RUN_ERRORS, e.RunOver),
)
async def abandon(run_id: str, request: Request) -> MsgpackResponse:
    team_id = await team_of(request)
    return MsgpackResponse(
        (await unabandoned(_service(request).abandon(team_id, run_id))).to_wire()
    )
