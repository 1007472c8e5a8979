"""Server settings, from arguments or ``MULTION_*`` environment variables."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class ServerSettings(BaseSettings):
    """Limits and sizes of a MultiON server; e.g. ``MULTION_WORKERS=4`` sets ``workers``."""

    model_config = SettingsConfigDict(env_prefix="MULTION_", frozen=True)

    host: str = "127.0.0.1"
    port: int = Field(8000, ge=0, le=65535)
    workers: int = Field(1, ge=1, description="simulator worker processes")
    max_sessions: int = Field(64, ge=1)
    max_envs_per_session: int = Field(64, ge=1)
    max_envs_total: int = Field(256, ge=1)
    idle_timeout_s: float = Field(900.0, gt=0, description="sessions unused this long are closed")
    max_request_bytes: int = Field(32 * 1024 * 1024, ge=1024)
    worker_timeout_s: float = Field(
        300.0, gt=0, description="a worker that takes longer to answer is killed and replaced"
    )
    worker_start_timeout_s: float = Field(120.0, gt=0)
    worker_memory_mb: int = Field(
        8192,
        ge=1024,
        description="address-space limit of each simulator worker (RLIMIT_AS); the memory "
        "estimates of the sessions a worker holds must fit in it, less what the process itself "
        "needs",
    )
    allowed_dataset_dirs: list[Path] = Field(
        default_factory=list,
        description="directories whose dataset files (and mesh scenes) clients may name, besides "
        "the packaged datasets; empty: packaged datasets only. Env: a JSON list",
    )
