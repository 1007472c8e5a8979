"""The results database: teams, their tokens, runs and per-episode records (SQLAlchemy 2).

The schema is created and upgraded by the Alembic migrations in ``migrations/``
(:func:`multion.leaderboard.storage.upgrade`), never by ``create_all``, so a database made by an
older server upgrades in place.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    LargeBinary,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship
from sqlalchemy.types import TypeDecorator


def utcnow() -> dt.datetime:
    return dt.datetime.now(dt.timezone.utc)


class UTCDateTime(TypeDecorator[dt.datetime]):
    """A timezone-aware UTC date-time on every backend (SQLite stores naive values)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: dt.datetime | None, dialect: Any) -> dt.datetime | None:
        if value is not None and value.tzinfo is not None:
            value = value.astimezone(dt.timezone.utc)
        return value

    def process_result_value(self, value: dt.datetime | None, dialect: Any) -> dt.datetime | None:
        if value is not None and value.tzinfo is None:
            value = value.replace(tzinfo=dt.timezone.utc)
        return value


class Base(DeclarativeBase):
    pass


class Team(Base):
    __tablename__ = "teams"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(80), unique=True)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    tokens: Mapped[list[Token]] = relationship(back_populates="team")


class Token(Base):
    """An API token: ``mlb_<key>_<secret>``; only SHA-256(secret) is stored."""

    __tablename__ = "tokens"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    key: Mapped[str] = mapped_column(String(32), unique=True, index=True)
    secret_hash: Mapped[str] = mapped_column(String(64))
    team_id: Mapped[int] = mapped_column(ForeignKey("teams.id"))
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    revoked_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime(), nullable=True)
    team: Mapped[Team] = relationship(back_populates="tokens")


class Run(Base):
    """A submission run and, while it is going, the state needed to resume it anywhere."""

    __tablename__ = "runs"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    team_id: Mapped[int] = mapped_column(ForeignKey("teams.id"), index=True)
    track: Mapped[str] = mapped_column(String(40))
    phase: Mapped[str] = mapped_column(String(40))
    method: Mapped[str] = mapped_column(String(120))
    paper_url: Mapped[str | None] = mapped_column(String(500), nullable=True)
    code_url: Mapped[str | None] = mapped_column(String(500), nullable=True)
    baseline: Mapped[bool] = mapped_column(Boolean, default=False)
    sensors: Mapped[list[str]] = mapped_column(JSON)
    maps: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    episode_set: Mapped[str] = mapped_column(String(8), default="fixed", server_default="fixed")
    """``fixed``: the phase's one episode set; ``fresh``: episodes drawn for this run."""
    order: Mapped[list[int]] = mapped_column(JSON)
    """Fixed: indices into the phase's episode set, in the order this run plays them;
    fresh: 0..n-1 (its own episodes)."""
    state: Mapped[str] = mapped_column(String(16), default="running", index=True)
    """running, finished (every episode played), ended (stopped early), failed (server fault)."""
    end_reason: Mapped[str | None] = mapped_column(String(40), nullable=True)
    refunded: Mapped[bool] = mapped_column(Boolean, default=False)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow, index=True)
    finished_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime(), nullable=True)
    # the live state, written at every step (compare-and-set on `version`)
    version: Mapped[int] = mapped_column(Integer, default=0)
    position: Mapped[int] = mapped_column(Integer, default=-1)
    """The run-order number of the current (or last) episode; -1 before the first."""
    episode_active: Mapped[bool] = mapped_column(Boolean, default=False)
    seq: Mapped[int] = mapped_column(Integer, default=0)
    actions: Mapped[str] = mapped_column(Text, default="")
    """The current episode's actions so far, one digit each."""
    last_metrics: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    deadline: Mapped[dt.datetime | None] = mapped_column(UTCDateTime(), nullable=True)
    """When the current episode expires if no action (or next episode start) comes."""
    consecutive_timeouts: Mapped[int] = mapped_column(Integer, default=0)
    num_envs: Mapped[int] = mapped_column(Integer, default=1, server_default="1")
    """Lanes: episodes played at once (lane k plays episodes k, k + K …)."""
    lanes: Mapped[list[dict[str, Any]] | None] = mapped_column(JSON, nullable=True)
    """Every lane's state (the columns above hold lane 0's; None: runs stored before lanes)."""
    summary: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    """Aggregates with 95% bootstrap intervals, once the run is over."""
    episodes: Mapped[list[EpisodeRecord]] = relationship(
        back_populates="run", order_by="EpisodeRecord.position"
    )


class EpisodeRecord(Base):
    """One played (or missed) episode of a run: every metric and the full action sequence."""

    __tablename__ = "episodes"
    __table_args__ = (UniqueConstraint("run_id", "position"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    run_id: Mapped[str] = mapped_column(ForeignKey("runs.id"), index=True)
    position: Mapped[int] = mapped_column(Integer)
    episode_index: Mapped[int] = mapped_column(Integer)
    """Fixed runs: index in the phase's episode set (canonical order); fresh runs: the
    position."""
    episode_id: Mapped[str] = mapped_column(String(80))
    end_reason: Mapped[str] = mapped_column(String(40))
    """success, wrong_found, max_steps (the env's), timeout, not_played (the run's)."""
    metrics: Mapped[dict[str, Any]] = mapped_column(JSON)
    actions: Mapped[str] = mapped_column(Text, default="")
    seconds: Mapped[float] = mapped_column(Float, default=0.0)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    run: Mapped[Run] = relationship(back_populates="episodes")


class SecretFingerprint(Base):
    """A fingerprint of the challenge secret the database's runs were played with (one row).

    HMAC-SHA256 of a fixed label keyed by the secret: it tells whether a server is started with
    the same secret, and reveals nothing about the secret itself."""

    __tablename__ = "secret_fingerprint"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    fingerprint: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)


class EpisodePicture(Base):
    """The top-down picture of one of a run's first episodes (minival), drawn once after the run
    ended (:mod:`multion.leaderboard.web.pictures`); an empty ``png`` records a failed drawing."""

    __tablename__ = "episode_pictures"

    run_id: Mapped[str] = mapped_column(ForeignKey("runs.id"), primary_key=True)
    position: Mapped[int] = mapped_column(Integer, primary_key=True)
    png: Mapped[bytes] = mapped_column(LargeBinary)
    width: Mapped[int] = mapped_column(Integer)
    height: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
