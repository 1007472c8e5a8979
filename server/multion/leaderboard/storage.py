"""Opening the results database, migrating it, and the team / token operations.

A database URL is SQLAlchemy's: ``sqlite:///leaderboard.db`` (the embedded default: one file,
opened in WAL mode so readers never wait for the writer) or
``postgresql+psycopg://user:pass@host/db`` when several server replicas share one database.
A plain path is taken as a SQLite file.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import hashlib
import hmac
import re
import secrets
import unicodedata
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from sqlalchemy import Engine, create_engine, event, func, make_url, select
from sqlalchemy.exc import ArgumentError, OperationalError
from sqlalchemy.orm import Session, sessionmaker

from multion.config.errors import UsageError
from multion.leaderboard.models import Run, SecretFingerprint, Team, Token, utcnow

Answer = TypeVar("Answer")

MIGRATIONS_DIR = Path(__file__).resolve().parent / "migrations"
TOKEN_PREFIX = "mlb"
_TOKEN = re.compile(rf"{TOKEN_PREFIX}_([A-Za-z0-9]{{12}})_([A-Za-z0-9_-]{{20,100}})")
TEAM_RULE = (
    "1–80 letters (of any script), digits, spaces, '.', '_' or '-', starting with a letter or "
    "digit and not ending in a space"
)


class StorageError(UsageError, ValueError):
    """A database that cannot be opened, or an admin operation that cannot be done."""


def database_url(value: str) -> str:
    """A SQLAlchemy URL; a bare path (``results.db``) means a SQLite file."""
    if "://" in value:
        return value
    return f"sqlite:///{Path(value).expanduser().resolve()}"


def open_engine(url: str) -> Engine:
    """An engine for ``url``; SQLite files get WAL mode, a busy timeout and foreign keys."""
    url = database_url(url)
    try:
        if url.startswith("sqlite"):
            engine = create_engine(url, connect_args={"timeout": 30, "check_same_thread": False})
            event.listen(engine, "connect", _sqlite_pragmas)
        else:
            engine = create_engine(url, pool_pre_ping=True)
    except (ArgumentError, ImportError) as error:
        raise StorageError(f"cannot use database URL {url!r}: {error}") from None
    return engine


def _sqlite_pragmas(connection: Any, record: Any) -> None:
    cursor = connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=NORMAL")  # WAL + NORMAL: durable across app crashes
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.close()


def upgrade(engine: Engine) -> None:
    """Create or upgrade the schema to the newest Alembic revision."""
    from alembic import command
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    try:
        with engine.begin() as connection:
            config.attributes["connection"] = connection
            command.upgrade(config, "head")
    except OperationalError as error:
        raise StorageError(
            f"cannot open or migrate the database {engine.url!r}: {error.orig}"
        ) from None


def current_revision(engine: Engine) -> str | None:
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as connection:
        return MigrationContext.configure(connection).get_current_revision()


@dataclass
class Database:
    """An engine and its session factory; ``Database.open(url)`` migrates to the newest schema."""

    engine: Engine
    sessions: sessionmaker[Session]

    @classmethod
    def open(cls, url: str, migrate: bool = True) -> Database:
        engine = open_engine(url)
        if migrate:
            upgrade(engine)
        return cls(engine, sessionmaker(engine, expire_on_commit=False))

    async def transaction(self, work: Callable[[Session], Answer]) -> Answer:
        """Run ``work(session)`` in a thread, in one transaction."""

        def run() -> Answer:
            with self.sessions.begin() as session:
                return work(session)

        return await asyncio.to_thread(run)

    @classmethod
    def open_existing(cls, url: str, hint: str = "") -> Database:
        """Open (and upgrade) a database that exists and has the leaderboard's schema; never
        create one (StorageError naming the URL, and ``hint`` on how to choose another)."""
        full = database_url(url)
        missing = f"no leaderboard database at {full}{hint}; `multion leaderboard init` or `multion serve` creates one"
        if full.startswith("sqlite"):
            path = make_url(full).database
            if not path or path == ":memory:" or not Path(path).is_file():
                raise StorageError(missing)
        engine = open_engine(full)
        try:
            revision = current_revision(engine)
        except OperationalError as error:
            engine.dispose()
            raise StorageError(f"cannot open the database {full}: {error.orig}") from None
        if revision is None:
            engine.dispose()
            raise StorageError(missing)
        upgrade(engine)
        return cls(engine, sessionmaker(engine, expire_on_commit=False))

    def close(self) -> None:
        self.engine.dispose()


# ---------------------------------------------------------------------- the challenge secret
FINGERPRINT_LABEL = b"multion leaderboard: fingerprint of the challenge secret, v1"


def secret_fingerprint(secret: str) -> str:
    """HMAC-SHA256 of a fixed label keyed by the secret: equal for equal secrets, and no help
    in finding the secret (it is never stored)."""
    return hmac.new(secret.encode("utf-8"), FINGERPRINT_LABEL, hashlib.sha256).hexdigest()


def check_secret(session: Session, secret: str, remember: bool = True) -> None:
    """StorageError if the database was used with another secret (its runs' hidden episodes
    could not be replayed or continued); with ``remember``, store the fingerprint on first use."""
    given = secret_fingerprint(secret)
    stored = session.scalar(select(SecretFingerprint).order_by(SecretFingerprint.id))
    if stored is None:
        if not remember:
            return
        session.add(SecretFingerprint(fingerprint=given))
        session.flush()
        return
    if not hmac.compare_digest(stored.fingerprint, given):
        raise StorageError(
            "the challenge secret is not the one this database was used with (its fingerprint, "
            f"stored on {stored.created_at:%Y-%m-%d %H:%M} UTC, differs): the hidden episodes "
            "would not be the ones its runs played. Start with the original secret (the "
            "challenge file's `secret` or the variable its `secret_env` names), or give another "
            "--database for a new challenge"
        )


# ---------------------------------------------------------------------- teams and tokens
def hash_secret(secret: str) -> str:
    return hashlib.sha256(secret.encode("utf-8")).hexdigest()


def valid_team_name(name: str) -> bool:
    """Letters of any script (Très, Zürich, 東京, with their combining marks), digits, spaces,
    '.', '_', '-'; 1–80 characters, starting with a letter or digit, not ending in a space."""
    return (
        0 < len(name) <= 80 and name[0].isalnum() and not name[-1].isspace()
        and all(c.isalnum() or c in " ._-" or unicodedata.category(c).startswith("M") for c in name)
    )  # fmt: skip


def add_team(session: Session, name: str) -> tuple[Team, str]:
    """A new team and its first token (returned once, never stored in clear). Names are
    stored in Unicode NFC, and may not differ from another team's by case alone (pages and
    people would take them for one team)."""
    name = unicodedata.normalize("NFC", name)
    if not valid_team_name(name):
        raise StorageError(f"team name {name!r}: {TEAM_RULE}")
    same = _same_name(session, name)
    if same is not None:
        differs = (
            "" if same.name == name else f" (names may not differ by case alone: {same.name!r})"
        )
        raise StorageError(
            f"a team named {name!r} already exists{differs} (`multion leaderboard token add`)"
        )
    team = Team(name=name)
    session.add(team)
    session.flush()
    return team, add_token(session, team)


def add_token(session: Session, team: Team) -> str:
    key = "".join(secrets.choice("abcdefghijkmnpqrstuvwxyz23456789") for _ in range(12))
    secret = secrets.token_urlsafe(32)
    session.add(Token(key=key, secret_hash=hash_secret(secret), team=team))
    session.flush()
    return f"{TOKEN_PREFIX}_{key}_{secret}"


def find_team(session: Session, name: str) -> Team:
    """The team of exactly this name; a name that differs by case only is suggested."""
    name = unicodedata.normalize("NFC", name)
    team = session.scalar(select(Team).where(Team.name == name))
    if team is None:
        same = _same_name(session, name)
        hint = f" (did you mean {same.name!r}?)" if same is not None else ""
        raise StorageError(f"no team named {name!r}{hint}")
    return team


def _same_name(session: Session, name: str) -> Team | None:
    """The team whose name equals ``name`` but for case (Unicode case folding, which SQL's
    lower() does not do for every script: compared here, over the few teams there are)."""
    key = name.casefold()
    return next((t for t in session.scalars(select(Team)) if t.name.casefold() == key), None)


def revoke_tokens(session: Session, team: Team, key: str | None = None) -> int:
    """Revoke the team's tokens (or the one whose key is ``key``); returns how many."""
    count = 0
    for token in team.tokens:
        if token.revoked_at is None and (key is None or token.key == key):
            token.revoked_at = utcnow()
            count += 1
    if key is not None and count == 0:
        raise StorageError(f"team {team.name!r} has no live token with key {key!r}")
    return count


def team_for_token(session: Session, presented: str) -> Team | None:
    """The team of a live token, or None; the secret part is compared in constant time."""
    match = _TOKEN.fullmatch(presented)
    if match is None:
        return None
    key, secret = match.groups()
    token = session.scalar(select(Token).where(Token.key == key))
    candidate = hash_secret(secret)
    stored = token.secret_hash if token is not None else hash_secret("")
    if not hmac.compare_digest(candidate, stored) or token is None or token.revoked_at is not None:
        return None
    return token.team


# ---------------------------------------------------------------------- quotas
def runs_counted(
    session: Session, team_id: int, track: str, phase: str, since: dt.datetime | None
) -> int:
    """Runs that count against a quota: every run created (abandoned ones too), minus refunds."""
    query = select(func.count(Run.id)).where(
        Run.team_id == team_id, Run.track == track, Run.phase == phase, Run.refunded.is_(False)
    )
    if since is not None:
        query = query.where(Run.created_at >= since)
    return int(session.scalar(query) or 0)


def daily_quota_reopens(
    session: Session, team_id: int, track: str, phase: str, now: dt.datetime, quota: int
) -> dt.datetime:
    """When a team that has used its daily ``quota`` may start a run again: once enough of
    its counted runs of the last 24 hours are more than 24 hours old."""
    day = dt.timedelta(days=1)
    created = session.scalars(
        select(Run.created_at)
        .where(Run.team_id == team_id, Run.track == track, Run.phase == phase)
        .where(Run.refunded.is_(False), Run.created_at >= now - day)
        .order_by(Run.created_at)
    ).all()
    # with n >= quota runs in the window, the (n - quota + 1)-th oldest must leave it
    return created[len(created) - quota] + day
