"""Runs written straight into a results database (no play): for the tests of what the pages and
commands show of given runs (ranks, refunds, runs that played nothing)."""

from __future__ import annotations

import contextlib
import datetime as dt
import secrets
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from multion.leaderboard.models import Run, Team
from multion.leaderboard.results import missed_metrics, summarize
from multion.leaderboard.storage import Database

START = dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc)


@dataclass(frozen=True)
class StoredRun:
    """A run to store: its per-episode ranking values (``None``: an episode the run did not
    play, recorded as ``missed`` says), its state and when it ended (minutes after START)."""

    team: str
    method: str
    values: Sequence[float | None]
    track: str = "1-on"
    phase: str = "minival"
    state: str = "finished"
    minutes: float = 0.0
    missed: str = "not_played"
    refunded: bool = False
    end_reason: str | None = None
    baseline: bool = False
    extra: dict[str, Any] = field(default_factory=dict)


def records(run: StoredRun) -> list[dict[str, Any]]:
    return [
        missed_metrics(1, run.missed)
        if v is None
        else {"ppl": v, "progress": v, "success": float(v > 0.5), "spl": v,
              "end_reason": "success" if v > 0.5 else "max_steps"}
        for v in run.values
    ]  # fmt: skip


def store_runs(url: str, runs: list[StoredRun], primary: str = "ppl") -> list[str]:
    """Write ``runs`` (and their teams) into the database at ``url``; returns the run ids."""
    db = Database.open(url)
    ids: list[str] = []
    try:
        with db.sessions.begin() as session:
            teams = {name: Team(name=name) for name in dict.fromkeys(r.team for r in runs)}
            session.add_all(teams.values())
            session.flush()
            for run in runs:
                ids.append(secrets.token_hex(16))
                ended = START + dt.timedelta(minutes=run.minutes)
                session.add(Run(
                    id=ids[-1], team_id=teams[run.team].id, track=run.track, phase=run.phase,
                    method=run.method, sensors=["goal"], maps={}, order=list(range(len(run.values))),
                    state=run.state, end_reason=run.end_reason, refunded=run.refunded,
                    baseline=run.baseline, created_at=ended - dt.timedelta(minutes=1),
                    finished_at=ended, summary=summarize(records(run), primary), **run.extra,
                ))  # fmt: skip
    finally:
        db.close()
    return ids


@contextlib.contextmanager
def pages_client(challenge: Path, url: str) -> Iterator[Any]:
    """The leaderboard app in-process (FastAPI's TestClient), pictures and warm-up off."""
    from fastapi.testclient import TestClient

    from multion.api.app import create_app
    from multion.api.settings import ServerSettings
    from multion.leaderboard.app import LeaderboardExtension
    from multion.leaderboard.settings import LeaderboardSettings

    settings = LeaderboardSettings(
        challenge=challenge, database=url, warm_up=False, draw_pictures=False
    )
    app = create_app(ServerSettings(workers=1), [LeaderboardExtension(settings)])
    with TestClient(app) as client:
        yield client
