"""The results database on SQLite and on a real PostgreSQL: migrations, tokens, quotas, the
per-step compare-and-set, and results that survive reopening."""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterator

import pytest
from sqlalchemy import inspect, select

from multion.leaderboard.challenge import Challenge
from multion.leaderboard.models import EpisodeRecord, Run, Token, utcnow
from multion.leaderboard.run_store import (
    EpisodeResult,
    LaneState,
    RunMoved,
    RunState,
    create_run,
    finish_run,
    save_state,
)
from multion.leaderboard.storage import (
    Database,
    StorageError,
    add_team,
    add_token,
    current_revision,
    find_team,
    revoke_tokens,
    team_for_token,
)
from multion_client import errors


@pytest.fixture(params=["sqlite", "postgresql"])
def db(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Database]:
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path_factory.mktemp('db') / 'results.db'}"
    else:
        url = request.getfixturevalue("postgres_url")
    database = Database.open(url)
    with database.engine.begin() as connection:  # a clean slate on the shared PostgreSQL
        for table in (
            "episode_pictures",
            "episodes",
            "runs",
            "tokens",
            "teams",
            "secret_fingerprint",
        ):
            connection.exec_driver_sql(f"DELETE FROM {table}")
    yield database
    database.close()


def test_migrations_make_the_schema(db: Database) -> None:
    assert current_revision(db.engine) == "0005"
    tables = set(inspect(db.engine).get_table_names())
    assert {
        "teams",
        "tokens",
        "runs",
        "episodes",
        "secret_fingerprint",
        "episode_pictures",
        "alembic_version",
    } <= tables
    Database.open(str(db.engine.url.render_as_string(hide_password=False))).close()  # idempotent
    if db.engine.dialect.name == "sqlite":
        with db.engine.connect() as connection:
            assert connection.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"


def test_tokens_are_stored_hashed_and_can_be_revoked(db: Database) -> None:
    with db.sessions.begin() as session:
        team, token = add_team(session, "Team Rocket")
        second = add_token(session, team)
    with db.sessions() as session:
        stored = session.scalars(select(Token)).all()
        assert len(stored) == 2
        assert all(token not in (t.secret_hash, t.key) and len(t.secret_hash) == 64 for t in stored)
        assert team_for_token(session, token).name == "Team Rocket"
        assert team_for_token(session, token[:-2] + "zz") is None
        assert team_for_token(session, "nonsense") is None
    with db.sessions.begin() as session:
        key = token.split("_")[1]
        assert revoke_tokens(session, find_team(session, "Team Rocket"), key) == 1
    with db.sessions() as session:
        assert team_for_token(session, token) is None
        assert team_for_token(session, second) is not None
    with db.sessions.begin() as session, pytest.raises(StorageError, match="already exists"):
        add_team(session, "Team Rocket")


def _run(team_id: int, run_id: str, order: list[int]) -> Run:
    return Run(id=run_id, team_id=team_id, track="1-on", phase="test-standard", method="m",
               sensors=["goal"], maps={}, order=order, created_at=utcnow())  # fmt: skip


def test_quota_state_and_results(db: Database, challenge: Challenge) -> None:
    track = challenge.track("1-on")
    phase = track.phase("test-standard")  # total_quota = 1
    with db.sessions.begin() as session:
        team, _ = add_team(session, "solo")
        create_run(session, _run(team.id, "r1", [1, 0]), track, phase, utcnow())
    with db.sessions.begin() as session, pytest.raises(errors.QuotaExceeded, match="total quota"):
        create_run(session, _run(team.id, "r2", [0, 1]), track, phase, utcnow())
    lane = LaneState(position=0, episode_active=True, seq=2, actions=[1, 2], deadline=utcnow())
    state = RunState(lanes=[lane])
    with db.sessions.begin() as session:
        save_state(session, "r1", state, [])
    stale = RunState(version=0)
    with db.sessions.begin() as session, pytest.raises(RunMoved):
        save_state(session, "r1", stale, [])  # another writer already moved the run on
    metrics = {"success": 1.0, "progress": 1.0, "spl": 0.5, "ppl": 0.5, "end_reason": "success"}
    result = EpisodeResult(0, 1, "hidden-1", "success", metrics, "12", 0.3)
    with db.sessions.begin() as session:
        summary = finish_run(session, "r1", state, [result], "ended", "abandoned", track,
                             ["hidden-1", "hidden-0"], [1, 0])  # fmt: skip
    assert summary["episodes"] == 2 and summary["success"]["mean"] == 0.5
    reopened = Database.open(db.engine.url.render_as_string(hide_password=False))
    try:
        with reopened.sessions() as session:
            run = session.get(Run, "r1")
            assert run.state == "ended" and run.summary == summary
            assert run.created_at.tzinfo is not None and run.created_at <= utcnow()
            records = session.scalars(select(EpisodeRecord).order_by(EpisodeRecord.position)).all()
            assert [(r.end_reason, r.actions) for r in records] == [
                ("success", "12"),
                ("not_played", ""),
            ]
            assert records[0].metrics == metrics
    finally:
        reopened.close()
    assert utcnow() - run.created_at < dt.timedelta(minutes=5)


def test_daily_quota_counts_the_last_24_hours_and_skips_refunds(
    db: Database, challenge: Challenge
) -> None:
    from dataclasses import replace

    track = challenge.track("1-on")
    phase = replace(track.phase("minival"), daily_quota=2)
    now = utcnow()
    with db.sessions.begin() as session:
        team, _ = add_team(session, "daily")
        old = _run(team.id, "old", [0])
        old.phase, old.created_at = "minival", now - dt.timedelta(hours=25)
        refunded = _run(team.id, "refunded", [0])
        refunded.phase, refunded.refunded = "minival", True
        session.add_all([old, refunded])
    for run_id in ("today-1", "today-2"):
        with db.sessions.begin() as session:
            run = _run(team.id, run_id, [0])
            run.phase, run.created_at = "minival", now
            create_run(session, run, track, phase, now)
    with (
        db.sessions.begin() as session,
        pytest.raises(errors.QuotaExceeded, match="daily quota is 2") as refused,
    ):
        run = _run(team.id, "today-3", [0])
        run.phase = "minival"
        create_run(session, run, track, phase, now)
    # the answer says when the next run is allowed: when today-1 is a day old
    later = now + dt.timedelta(hours=3)
    reopens = f"{now + dt.timedelta(days=1):%Y-%m-%d %H:%M:%S} UTC (in 24 h 0 min)"
    assert f"the next run is allowed from {reopens}" in str(refused.value)
    with (
        db.sessions.begin() as session,
        pytest.raises(errors.QuotaExceeded, match="in 21 h 0 min"),
    ):
        run = _run(team.id, "later", [0])
        run.phase = "minival"
        create_run(session, run, track, phase, later)


def test_sealed_results_open_at_their_date(challenge: Challenge) -> None:
    sealed = challenge.track("1-on-oracle").phase("test-challenge")
    assert not sealed.results_visible(utcnow())
    assert sealed.results_visible(sealed.sealed_until)
    assert challenge.track("1-on").phase("minival").results_visible(utcnow())
