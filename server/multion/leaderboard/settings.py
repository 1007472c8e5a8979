"""Leaderboard settings of a server, from ``multion serve`` options or environment variables."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class LeaderboardSettings(BaseSettings):
    """``multion serve --challenge FILE --database URL``; e.g. ``MULTION_LEADERBOARD_DATABASE``."""

    model_config = SettingsConfigDict(env_prefix="MULTION_LEADERBOARD_", frozen=True)

    challenge: Path = Field(description="the challenge file (TOML): tracks, phases, secret")
    database: str = Field(
        "sqlite:///leaderboard.db",
        description="SQLAlchemy URL (sqlite:///FILE, postgresql+psycopg://…) or a SQLite path",
    )
    token_cache_s: float = Field(
        5.0, ge=0, description="a checked token is trusted this long (revocations take this long)"
    )
    expire_interval_s: float = Field(
        5.0, gt=0, description="how often late episodes of silent clients are expired"
    )
    docs_url: str | None = Field(
        None,
        description="where the rules page links the participants' guide; none: the server's "
        "own /leaderboard/guide (docs/leaderboard.md of the source tree it runs from)",
    )
    draw_pictures: bool = Field(
        True, description="draw the pictures of ended minival runs in the background"
    )
    picture_interval_s: float = Field(
        5.0, gt=0, description="how often ended minival runs are looked for to draw their pictures"
    )
    videos: bool = Field(
        True,
        description="film the episodes of ended minival runs for their run pages (needs the "
        "video extra: pip install -e '.[video]')",
    )
    video_dir: Path | None = Field(
        None,
        description="where the run pages' films are kept; none: a temporary folder named after "
        "the database",
    )
    video_cache_mib: int = Field(
        2048,
        ge=64,
        le=1_000_000,
        description="MiB of films kept at most (the least recently watched removed)",
    )
    warm_up: bool = Field(
        True,
        description="generate the hidden episodes and prepare the web pages (their templates "
        "and queries) at start-up rather than at the first run or page view",
    )
