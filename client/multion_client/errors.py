"""Typed errors of the MultiON API, shared by the server (which raises them) and the client.

Every error a server sends has a machine-readable ``code`` and a human-readable ``message``
(wire form: ``{"error": {"code": ..., "message": ...}}``). :func:`error_from_code` turns that
back into the matching exception class, so client code can ``except SessionNotFound:``.
Some classes also derive from the builtin the in-process environment raises (``ValueError`` for
an illegal action, ``RuntimeError`` for stepping an ended episode), so one ``except`` clause
works for both a local ``MultiONEnv`` and a ``RemoteEnv``.
"""

from __future__ import annotations


class MultiONError(Exception):
    """Base of every API error: the server's ``code``, its ``message`` and the HTTP status."""

    code = "error"
    status = 500

    def __init__(self, message: str, code: str | None = None, status: int | None = None) -> None:
        super().__init__(message)
        self.message = message
        if code is not None:
            self.code = code
        if status is not None:
            self.status = status

    def __str__(self) -> str:
        return f"[{self.code}] {self.message}"

    def to_wire(self) -> dict[str, dict[str, str]]:
        return {"error": {"code": self.code, "message": self.message}}


# ---------------------------------------------------------------------- 4xx: the request's fault
class BadRequest(MultiONError):
    """The request is not valid (wrong fields, wrong number of actions, …)."""

    code, status = "bad_request", 400


class MalformedMessage(BadRequest):
    """A body is not valid msgpack, or not the message the route expects."""

    code, status = "malformed_message", 400


class InvalidAction(BadRequest, ValueError):
    """An action is not one of 0..3 (FOUND, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT)."""

    code, status = "invalid_action", 400


class InvalidConfig(BadRequest):
    """The environment config names an unknown field, has an ill-typed value or is inconsistent."""

    code, status = "invalid_config", 422


class InvalidEpisode(BadRequest):
    """An episode (inline, by index or by id) cannot be used."""

    code, status = "invalid_episode", 422


class PathNotAllowed(BadRequest):
    """A file path (``dataset``, a mesh ``scene_id``) outside the directories the server may read."""

    code, status = "path_not_allowed", 403


class Unauthorized(MultiONError):
    """A leaderboard route without a valid token (missing, malformed, unknown or revoked)."""

    code, status = "unauthorized", 401


class SessionsNotAllowed(MultiONError):
    """Plain sessions are off on this server (``--sessions off``: leaderboard runs only)."""

    code, status = "sessions_not_allowed", 403


class NotAllowedInRun(BadRequest):
    """Something a run does not let a participant choose: seeds, reset options, episodes, or a
    sensor (oracle maps, goal distance) the track does not allow."""

    code, status = "not_allowed_in_run", 403


class NotFound(MultiONError):
    """No such route."""

    code, status = "not_found", 404


class SessionNotFound(NotFound):
    """No session with this id (never created, closed, or reaped after being idle)."""

    code, status = "session_not_found", 404


class RunNotFound(NotFound):
    """No run with this id for this team (another team's runs are not visible)."""

    code, status = "run_not_found", 404


class UnknownTrack(NotFound):
    """No such track or phase in the server's challenge, or the server runs no challenge."""

    code, status = "unknown_track", 404


class MethodNotAllowed(BadRequest):
    code, status = "method_not_allowed", 405


class EpisodeOver(MultiONError, RuntimeError):
    """``step`` after an episode ended in a session without auto-reset: call ``reset`` first."""

    code, status = "episode_over", 409


class NotReset(MultiONError, RuntimeError):
    """``observe`` before the first ``reset`` of a session."""

    code, status = "not_reset", 409


class EpisodeInProgress(MultiONError):
    """A run's next episode was asked for before the current one ended."""

    code, status = "episode_in_progress", 409


class SequenceMismatch(MultiONError):
    """A run step whose (episode, seq) is neither the next one nor a retry of the last one."""

    code, status = "sequence_mismatch", 409


class RunOver(MultiONError):
    """The run has ended (finished, stopped early or failed): nothing more can be played."""

    code, status = "run_over", 409


class RequestTooLarge(MultiONError):
    code, status = "request_too_large", 413


class LimitExceeded(MultiONError):
    """A server limit (sessions, environments) would be exceeded; retry later or use fewer."""

    code, status = "limit_exceeded", 429


class TooManySessions(LimitExceeded):
    code, status = "too_many_sessions", 429


class TooManyEnvs(LimitExceeded):
    code, status = "too_many_envs", 429


class MemoryBudgetExceeded(LimitExceeded):
    """The session's memory estimate does not fit what the simulator workers have free now."""

    code, status = "memory_budget_exceeded", 429


class QuotaExceeded(LimitExceeded):
    """The team has used its run quota for this phase (daily or total)."""

    code, status = "quota_exceeded", 429


# ---------------------------------------------------------------------- 5xx: the server's fault
class InternalError(MultiONError):
    code, status = "internal_error", 500


class WorkerFailed(MultiONError):
    """The simulator process holding this session died; the session is lost (close it)."""

    code, status = "worker_failed", 503


class ServerUnavailable(MultiONError):
    """The client could not reach the server (raised by the client, never sent by a server)."""

    code, status = "server_unavailable", 503


ERRORS: dict[str, type[MultiONError]] = {
    cls.code: cls
    for cls in (
        MultiONError,
        BadRequest,
        MalformedMessage,
        InvalidAction,
        InvalidConfig,
        InvalidEpisode,
        PathNotAllowed,
        Unauthorized,
        SessionsNotAllowed,
        NotAllowedInRun,
        NotFound,
        SessionNotFound,
        RunNotFound,
        UnknownTrack,
        MethodNotAllowed,
        EpisodeOver,
        NotReset,
        EpisodeInProgress,
        SequenceMismatch,
        RunOver,
        RequestTooLarge,
        LimitExceeded,
        TooManySessions,
        TooManyEnvs,
        MemoryBudgetExceeded,
        QuotaExceeded,
        InternalError,
        WorkerFailed,
        ServerUnavailable,
    )
}
"""Error code → exception class."""

_BY_STATUS: dict[int, type[MultiONError]] = {
    400: BadRequest,
    401: Unauthorized,
    403: PathNotAllowed,
    404: NotFound,
    405: MethodNotAllowed,
    409: EpisodeOver,
    413: RequestTooLarge,
    422: BadRequest,
    429: LimitExceeded,
    503: ServerUnavailable,
}


def error_from_code(code: str, message: str, status: int | None = None) -> MultiONError:
    """The exception for a server error; unknown codes fall back on the HTTP status."""
    cls = ERRORS.get(code)
    if cls is None:
        cls = _BY_STATUS.get(
            status or 500, BadRequest if 400 <= (status or 500) < 500 else MultiONError
        )
    return cls(message, code=code, status=status)
