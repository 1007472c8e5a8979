"""Server settings, from arguments or ``MULTION_*`` environment variables."""

from __future__ import annotations

import re
import uuid
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from multion.common.processes import address_space_limit
from multion.config.ranges import ConfigError

ID_LENGTH = 32
"""Session and run ids are at most this long (the leaderboard's ``runs.id`` is String(32))."""
REPLICA_PATTERN = re.compile(r"[a-z0-9]{1,8}")
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")
"""Listen addresses that only this machine can reach (``live_view = "auto"`` is on there)."""
MIN_WORKER_MEMORY_MB = 1024
"""The least address space a simulator worker starts in (the interpreter, PyBullet, numpy)."""


class ServerSettings(BaseSettings):
    """Limits and sizes of a MultiON server; e.g. ``MULTION_WORKERS=4`` sets ``workers``."""

    model_config = SettingsConfigDict(env_prefix="MULTION_", frozen=True)

    host: str = Field("127.0.0.1", description="address to listen on (0.0.0.0 for every interface)")
    port: int = Field(8000, ge=0, le=65535, description="TCP port")
    workers: int = Field(
        1, ge=1, description="simulator worker processes; sessions are spread over them"
    )
    max_sessions: int = Field(64, ge=1, description="most open sessions")
    max_envs_per_session: int = Field(64, ge=1, description="most environments in one session")
    max_envs_total: int = Field(256, ge=1, description="most environments over all sessions")
    idle_timeout_s: float = Field(
        900.0, gt=0, description="close sessions unused for this many seconds"
    )
    max_request_bytes: int = Field(
        32 * 1024 * 1024, ge=1024, description="largest request body accepted, in bytes"
    )
    worker_timeout_s: float = Field(
        300.0, gt=0, description="kill and replace a worker silent this many seconds"
    )
    worker_start_timeout_s: float = Field(
        120.0, gt=0, description="give up on a simulator worker not ready after this many seconds"
    )
    worker_memory_mb: int = Field(
        8192,
        ge=MIN_WORKER_MEMORY_MB,
        description="address-space limit of each simulator worker (RLIMIT_AS), and the room its "
        "sessions' memory estimates share, less what the process itself needs; lowered to this "
        "process's own limit (ulimit -v) when that is lower and this is not given",
    )
    sessions: Literal["open", "token", "off"] = Field(
        "open",
        description="who may open plain sessions (the /v1/sessions routes): anyone (open); "
        "holders of a team token (token: needs a challenge); nobody (off: a server for "
        "leaderboard runs only)",
    )
    sessions_per_client: int = Field(
        16,
        ge=1,
        le=1024,
        description="plain sessions one client may hold at once; a client is its team token "
        "(--sessions token), else its IP address (behind a proxy: the forwarded address)",
    )
    run_reserve: float = Field(
        0.5,
        ge=0.0,
        le=0.9,
        description="with a challenge: the share of each simulator worker's memory and of "
        "max_sessions that plain sessions cannot take, kept for leaderboard runs",
    )
    allowed_dataset_dirs: list[Path] = Field(
        default_factory=list,
        description="directories whose dataset files (and mesh scenes) clients may name, besides "
        "the packaged datasets; empty: packaged datasets only. Env: a JSON list",
    )
    live_view: Literal["auto", "local", "off"] = Field(
        "auto",
        description="a page per plain session at /v1/live/SESSION_ID showing its RGB-D, map and "
        "metrics as it steps, to requests from this machine only (local); off; or auto: local "
        "when the server listens on a loopback address only, else off. Never for leaderboard "
        "runs, nor for requests a proxy forwarded",
    )
    replica: str | None = Field(
        None,
        description="this replica's name, 1-8 characters from a-z and 0-9, or none; it prefixes "
        "every session and run id (NAME-<hex>) so that a reverse proxy can send a session's "
        "requests to the replica that holds it (see docker/README.md)",
    )

    @field_validator("replica", mode="before")
    @classmethod
    def _check_replica(cls, value: object) -> object:
        if value == "":  # MULTION_REPLICA= (empty) means no replica name
            return None
        if value is not None and not (isinstance(value, str) and REPLICA_PATTERN.fullmatch(value)):
            raise ValueError(
                f"replica must be 1-8 characters from a-z and 0-9 "
                f"(pattern {REPLICA_PATTERN.pattern}), got {value!r}"
            )
        return value

    def live_view_on(self) -> bool:
        """Whether the live view answers (still only to requests from this machine)."""
        if self.live_view == "auto":
            return self.host in LOOPBACK_HOSTS
        return self.live_view == "local"

    def new_id(self) -> str:
        """A new session or run id: 32 hex digits, or with a replica name ``NAME-`` and as many
        hex digits as fit in :data:`ID_LENGTH` characters (23 to 30, of which ≥ 86 random bits)."""
        digits = uuid.uuid4().hex
        if self.replica is None:
            return digits
        return f"{self.replica}-{digits[: ID_LENGTH - len(self.replica) - 1]}"


def replica_of(some_id: str) -> str | None:
    """The replica name a session or run id starts with (``NAME-``), or None."""
    name, dash, _ = some_id.partition("-")
    return name if dash and REPLICA_PATTERN.fullmatch(name) else None


def fit_outer_memory_limit(
    settings: ServerSettings, outer_bytes: int | None = None
) -> tuple[ServerSettings, str | None]:
    """Settings whose ``worker_memory_mb`` fits under this process's own address-space limit
    (``ulimit -v``, ``prlimit --as``; ``outer_bytes`` to test), which every worker inherits
    and cannot raise: the default is lowered to it, with a warning to show; a value given
    above it, or a limit too low for any worker, is a ValueError naming the option."""
    if outer_bytes is None:
        outer_bytes = address_space_limit()
    if outer_bytes is None or settings.worker_memory_mb * 2**20 <= outer_bytes:
        return settings, None
    outer_mb = outer_bytes // 2**20
    option = "--worker-memory-mb (MULTION_WORKER_MEMORY_MB)"
    if outer_mb < MIN_WORKER_MEMORY_MB:
        raise ConfigError(
            f"this process's address-space limit (ulimit -v / prlimit --as) is {outer_mb} MiB, "
            f"below the {MIN_WORKER_MEMORY_MB} MiB a simulator worker needs ({option} is at "
            f"least {MIN_WORKER_MEMORY_MB}): raise the limit"
        )
    if "worker_memory_mb" in settings.model_fields_set:
        raise ConfigError(
            f"{option} is {settings.worker_memory_mb} MiB, above this process's address-space "
            f"limit (ulimit -v / prlimit --as) of {outer_mb} MiB, which the simulator workers "
            f"cannot exceed: give {outer_mb} or less, or raise the limit"
        )
    warning = (
        f"this process's address-space limit (ulimit -v / prlimit --as) is {outer_mb} MiB, "
        f"below the default {option} of {settings.worker_memory_mb} MiB: each simulator worker "
        f"gets {outer_mb} MiB (give {option} to choose a value up to {outer_mb})"
    )
    return settings.model_copy(update={"worker_memory_mb": outer_mb}), warning
