"""A small synchronous client for a MultiON server (one keep-alive HTTP connection pool)."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from types import TracebackType
from typing import Any

import httpx
import numpy as np

from multion_client.errors import MalformedMessage, MultiONError, ServerUnavailable, error_from_code
from multion_client.protocol import (
    CONTENT_TYPE,
    HEALTH_PATH,
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

DEFAULT_TIMEOUT_S = 120.0
"""Generous: a reset may load a new scene and build its navigable grid on the server."""


class Client:
    """Calls the ``/v1`` routes of one server and raises the typed errors of ``errors.py``.

    Connection failures are retried with exponential backoff (at most ``retries`` times) for
    idempotent calls (health, spec, observe, close) and for any call whose connection was never
    established; ``create_session``, ``reset`` and ``step`` are otherwise not retried, because
    the server may already have acted on them.
    """

    def __init__(
        self,
        base_url: str,
        timeout: float = DEFAULT_TIMEOUT_S,
        retries: int = 3,
        backoff_s: float = 0.2,
    ) -> None:
        if retries < 0:
            raise ValueError(f"retries must be ≥ 0, got {retries}")
        self.base_url = base_url.rstrip("/")
        self.retries = retries
        self.backoff_s = backoff_s
        self._http = httpx.Client(
            base_url=self.base_url,
            timeout=httpx.Timeout(timeout, connect=min(timeout, 10.0)),
            headers={"accept": CONTENT_TYPE},
        )

    # ------------------------------------------------------------------ routes
    def health(self) -> dict[str, Any]:
        """Server status: API version, live workers, sessions and environments."""
        return self._call("GET", HEALTH_PATH, idempotent=True)

    def spec(self) -> dict[str, Any]:
        """Actions, sensors, default config and limits; spaces are rebuilt as gymnasium spaces."""
        spec = self._call("GET", SPEC_PATH, idempotent=True)
        for key in ("observation_space", "action_space"):
            if key in spec:
                spec[key] = space_from_wire(spec[key])
        return spec

    def create_session(
        self, config: Mapping[str, Any] | None = None, num_envs: int = 1, auto_reset: bool = False
    ) -> SessionInfo:
        """Start ``num_envs`` environments with ``config`` (EnvConfig as nested dicts)."""
        message = CreateSession(dict(config or {}), num_envs, auto_reset)
        return SessionInfo.from_wire(self._call("POST", SESSIONS_PATH, message.to_wire()))

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

    def _call(
        self, method: str, path: str, body: dict[str, Any] | None = None, idempotent: bool = False
    ) -> Any:
        content = None if body is None else encode(body)
        headers = None if content is None else {"content-type": CONTENT_TYPE}
        for attempt in range(self.retries + 1):
            try:
                response = self._http.request(method, path, content=content, headers=headers)
                break
            except httpx.TransportError as error:
                # A refused connection never reached the server, so even a step is safe to resend.
                never_sent = isinstance(error, (httpx.ConnectError, httpx.ConnectTimeout))
                if not (idempotent or never_sent) or attempt == self.retries:
                    raise ServerUnavailable(
                        f"{method} {self.base_url}{path} failed: {type(error).__name__}: {error}"
                    ) from error
                time.sleep(min(self.backoff_s * 2**attempt, 2.0))
        if response.is_success:
            return decode(response.content)
        raise _error(response)


def _error(response: httpx.Response) -> MultiONError:
    try:
        error = Error.from_wire(decode(response.content))
    except MalformedMessage:
        text = response.text[:300] or response.reason_phrase
        return error_from_code(f"http_{response.status_code}", text, response.status_code)
    return error_from_code(error.code, error.message, response.status_code)


def _plain(action: Any) -> Any:
    """numpy integers become ints; anything else goes as is, for the server to judge."""
    if isinstance(action, (np.generic, np.ndarray)) and np.ndim(action) == 0:
        return action.item()
    return action
