"""A small synchronous client for a MultiON server (one keep-alive HTTP connection)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from types import TracebackType
from typing import Any

import numpy as np

from multion_client.errors import MalformedMessage, MultiONError, ServerUnavailable, error_from_code
from multion_client.protocol import (
    CONTENT_TYPE,
    HEALTH_PATH,
    RENDERER_HEADER,
    SESSIONS_PATH,
    SPEC_PATH,
    CreateSession,
    Error,
    Observations,
    Reset,
    SessionInfo,
    Step,
    StepResult,
    decode,
    encode,
    session_path,
    space_from_wire,
)
from multion_client.run_protocol import (
    CHALLENGE_PATH,
    RUNS_PATH,
    CreateRun,
    RunInfo,
    RunList,
    RunObservation,
    RunStatus,
    RunStep,
    StartEpisode,
    run_path,
)
from multion_client.transport import Connection, Response, TransportError

DEFAULT_TIMEOUT_S = 120.0
"""Generous: a reset may load a new scene and build its navigable grid on the server."""


class Client:
    """Calls the ``/v1`` routes of one server and raises the typed errors of ``errors.py``.

    Connection failures are retried with exponential backoff (at most ``retries`` times) for
    idempotent calls (health, spec, observe, close) and for any call whose connection was never
    established; ``create_session``, ``reset`` and ``step`` are otherwise not retried, because
    the server may already have acted on them. The leaderboard's run calls carry sequence
    numbers, so starting an episode and stepping a run are retried too.

    ``token`` (a team's leaderboard token) is sent as ``Authorization: Bearer``; only the run
    routes need it.
    """

    def __init__(
        self,
        base_url: str,
        timeout: float = DEFAULT_TIMEOUT_S,
        retries: int = 3,
        backoff_s: float = 0.2,
        token: str | None = None,
    ) -> None:
        if retries < 0:
            raise ValueError(f"retries must be ≥ 0, got {retries}")
        self.base_url = base_url.rstrip("/")
        self.retries = retries
        self.backoff_s = backoff_s
        self._http = Connection(
            self.base_url,
            timeout_s=timeout,
            connect_timeout_s=min(timeout, 10.0),
            headers={"accept": CONTENT_TYPE}
            | ({"authorization": f"Bearer {token}"} if token else {}),
        )

    # ------------------------------------------------------------------ routes
    def health(self) -> dict[str, Any]:
        """Server status: API version, live workers, sessions and environments."""
        return self._get_map(HEALTH_PATH)

    def spec(self) -> dict[str, Any]:
        """Actions, sensors, default config and limits; spaces are rebuilt as gymnasium spaces."""
        spec = self._get_map(SPEC_PATH)
        for key in ("observation_space", "action_space"):
            if key in spec:
                spec[key] = space_from_wire(spec[key])
        return spec

    def create_session(
        self, config: Mapping[str, Any] | None = None, num_envs: int = 1, auto_reset: bool = False
    ) -> SessionInfo:
        """Start ``num_envs`` environments with ``config`` (EnvConfig as nested dicts)."""
        message = CreateSession(dict(config or {}), num_envs, auto_reset)
        response = self._send("POST", SESSIONS_PATH, message.to_wire())
        info = SessionInfo.from_wire(decode(response.content))
        return dataclasses.replace(info, renderer=response.headers.get(RENDERER_HEADER))

    def reset(
        self,
        session_id: str,
        seeds: Sequence[int | None] | None = None,
        options: Sequence[Mapping[str, Any] | None] | None = None,
    ) -> Observations:
        """Reset every environment of the session (lists are per env; None: no seed/options)."""
        message = Reset(
            [None if s is None else int(s) for s in seeds or []],
            [None if o is None else dict(o) for o in options or []],
        )
        data = self._call("POST", session_path(session_id, "reset"), message.to_wire())
        return Observations.from_wire(data)

    def step(self, session_id: str, actions: Sequence[Any]) -> StepResult:
        """One action per environment of the session, in one request."""
        message = Step([_plain(a) for a in actions])
        data = self._call("POST", session_path(session_id, "step"), message.to_wire())
        return StepResult.from_wire(data)

    def observe(self, session_id: str) -> Observations:
        """The latest observations and infos, without acting."""
        data = self._call("GET", session_path(session_id, "observe"), idempotent=True)
        return Observations.from_wire(data)

    def close_session(self, session_id: str) -> None:
        """Free the session's environments on the server."""
        self._call("DELETE", session_path(session_id), idempotent=True)

    # ------------------------------------------------------------------ leaderboard runs
    def challenge(self) -> dict[str, Any]:
        """The server's challenge: tracks, phases, limits (no token needed)."""
        return self._get_map(CHALLENGE_PATH)

    def create_run(self, message: CreateRun) -> RunInfo:
        """Start a run (debits the team's quota; not retried once the request was sent)."""
        return RunInfo.from_wire(self._call("POST", RUNS_PATH, message.to_wire()))

    def start_episode(self, run_id: str, episode: int) -> RunObservation:
        """Start the run's episode number ``episode`` (retried safely: the server dedupes)."""
        body = StartEpisode(episode).to_wire()
        data = self._call("POST", run_path(run_id, "episodes"), body, idempotent=True)
        return RunObservation.from_wire(data)

    def run_step(self, run_id: str, episode: int, seq: int, action: Any) -> RunObservation:
        """Action ``seq`` of ``episode`` (retried safely: a repeated seq is not acted twice)."""
        body = RunStep(episode, seq, _plain(action)).to_wire()
        data = self._call("POST", run_path(run_id, "step"), body, idempotent=True)
        return RunObservation.from_wire(data)

    def run_observe(self, run_id: str, lane: int = 0) -> RunObservation:
        """Where a lane of the run stands (its last answer), to resume after a crash."""
        path = run_path(run_id, "observe") + (f"?lane={int(lane)}" if lane else "")
        return RunObservation.from_wire(self._call("GET", path, idempotent=True))

    def run_status(self, run_id: str) -> RunStatus:
        return RunStatus.from_wire(self._call("GET", run_path(run_id), idempotent=True))

    def list_runs(self) -> list[RunStatus]:
        return RunList.from_wire(self._call("GET", RUNS_PATH, idempotent=True)).runs

    def abandon_run(self, run_id: str) -> RunStatus:
        """End the run now; its missing episodes count as failures."""
        return RunStatus.from_wire(self._call("DELETE", run_path(run_id), idempotent=True))

    # ------------------------------------------------------------------ plumbing
    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _get_map(self, path: str) -> dict[str, Any]:
        """GET a route that answers a free-form map (health, spec, challenge)."""
        answer: dict[str, Any] = self._call("GET", path, idempotent=True)
        return answer

    def _call(
        self, method: str, path: str, body: dict[str, Any] | None = None, idempotent: bool = False
    ) -> Any:
        return decode(self._send(method, path, body, idempotent).content)

    def _send(
        self, method: str, path: str, body: dict[str, Any] | None = None, idempotent: bool = False
    ) -> Response:
        """The server's successful answer, or its error raised as a typed MultiONError."""
        content = None if body is None else encode(body)
        headers = None if content is None else {"content-type": CONTENT_TYPE}
        for attempt in range(self.retries + 1):
            try:
                response = self._http.request(method, path, content, headers)
                break
            except TransportError as error:
                # A refused connection never reached the server, so even a step is safe to resend.
                if not (idempotent or error.never_sent) or attempt == self.retries:
                    raise ServerUnavailable(
                        f"{method} {self.base_url}{path} failed: {error}"
                    ) from error
                time.sleep(min(self.backoff_s * 2**attempt, 2.0))
        if response.is_success:
            return response
        raise _error(response)


def _error(response: Response) -> MultiONError:
    try:
        error = Error.from_wire(decode(response.content))
    except MalformedMessage:
        text = response.text[:300] or response.reason
        return error_from_code(f"http_{response.status}", text, response.status)
    return error_from_code(error.code, error.message, response.status)


def _plain(action: Any) -> Any:
    """numpy integers become ints; anything else goes as is, for the server to judge."""
    if isinstance(action, (np.generic, np.ndarray)) and np.ndim(action) == 0:
        return action.item()
    return action
