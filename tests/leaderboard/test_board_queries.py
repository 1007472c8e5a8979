"""The leaderboard's ranking, read from a database of many stored runs, against the stored
aggregates themselves; and the pages bench, run small."""

from __future__ import annotations

import datetime as dt
import secrets
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import select

from multion.leaderboard.challenge_file import load_challenge, write_challenge
from multion.leaderboard.models import Run, Team
from multion.leaderboard.storage import Database
from multion.leaderboard.web import queries
from multion_agents.bench.pages import bench_challenge, fill_database, run_pages_bench


def fresh_database(request: pytest.FixtureRequest, backend: str, tmp_path: Path) -> str:
    if backend == "sqlite":
        return f"sqlite:///{tmp_path / 'results.db'}"
    server = request.getfixturevalue("postgres_url")  # skips without PostgreSQL
    import psycopg

    name = f"boards_{secrets.token_hex(4)}"
    plain = server.replace("postgresql+psycopg", "postgresql").rsplit("/", 1)[0] + "/postgres"
    with psycopg.connect(plain, autocommit=True) as connection:
        connection.execute(f"CREATE DATABASE {name}")
    return server.rsplit("/", 1)[0] + f"/{name}"


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_boards_rank_each_teams_best_run_with_ties(
    request: Any, backend: str, tmp_path: Path
) -> None:
    challenge = load_challenge(write_challenge(bench_challenge(5), tmp_path / "challenge.toml"))
    url = fresh_database(request, backend, tmp_path)
    fill_database(url, runs=240, episodes=5)
    db = Database.open(url)
    try:
        with db.sessions() as session:
            boards = queries.leaderboards(session, challenge, dt.datetime.now(dt.timezone.utc))
            stored = session.execute(select(Run, Team.name).join(Team)).all()
    finally:
        db.close()
    assert len(boards) == 6
    for board in boards:
        runs = [
            (r, team)
            for r, team in stored
            if (r.track, r.phase) == (board.track.name, board.phase.name)
        ]
        best: dict[str, float] = {}
        for run, team in runs:
            best[team] = max(best.get(team, -1.0), run.summary["ppl"]["mean"])
        assert sorted(row.team for row in board.rows) == sorted(best)
        by_id = {r.id: r for r, _ in runs}
        for row in board.rows:
            summary = by_id[row.run_id].summary
            assert row.scores["ppl"].mean == best[row.team] == summary["ppl"]["mean"]
            assert row.scores["progress"].low == summary["progress"]["low"]
            assert (row.completed, row.total) == (5, 5)
        means = [row.scores["ppl"].mean for row in board.rows]
        assert means == sorted(means, reverse=True)
        for k, row in enumerate(board.rows):  # competition ranking: 1, 2, 2, 4 …
            assert row.rank == 1 + sum(m > means[k] for m in means)
        leader = board.rows[0].scores["ppl"]
        for row in board.rows:
            mine = row.scores["ppl"]
            assert row.tied_with_leader == (mine.high >= leader.low and leader.high >= mine.low)
        assert any(row.tied_with_leader for row in board.rows[1:])
        assert not all(row.tied_with_leader for row in board.rows)


def test_the_pages_bench_runs() -> None:
    result = run_pages_bench(runs=12, episodes=3, repeats=2, verbose=False)
    assert set(result) >= {"leaderboard median ms", "run (test-standard) p95 ms"}
    assert all(value > 0 for value in result.values())


# ---------------------------------------------------------------------- issue 21: ties
VALUES = [0.1, 0.2, 0.3, 0.7, 0.05, 0.6, 0.9, 0.33]
SHUFFLED = [0.1, 0.2, 0.3, 0.05, 0.7, 0.9, 0.6, 0.33]


def _records(values: list[float]) -> list[dict[str, Any]]:
    return [
        {"ppl": v, "progress": v, "success": float(v > 0.5), "spl": v, "end_reason": "success"}
        for v in values
    ]


def test_equal_per_episode_values_give_equal_scores_ranks_and_intervals(tmp_path: Path) -> None:
    import numpy as np

    from multion.leaderboard.results import summarize

    # the same eight values played in another order: float means differ in the last bit
    assert float(np.mean(VALUES)) != float(np.mean(SHUFFLED))
    one, other = summarize(_records(VALUES), "ppl"), summarize(_records(SHUFFLED), "ppl")
    for metric in ("ppl", "progress", "success", "spl"):
        assert one[metric] == other[metric]  # mean, low and high to the last bit

    path = write_challenge(bench_challenge(8, (("1-on", 1),)), tmp_path / "challenge.toml")
    challenge = load_challenge(path)
    url = f"sqlite:///{tmp_path / 'results.db'}"
    start = dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc)
    runs = [  # team, state, minutes after start, values
        ("early", "finished", 1, VALUES),
        ("late", "finished", 9, SHUFFLED),
        ("low", "finished", 0, [v / 2 for v in VALUES]),
        ("mixed", "ended", 2, VALUES),  # ended first, then a finished run, equal scores
        ("mixed", "finished", 5, SHUFFLED),
        ("mixed", "finished", 7, VALUES),
    ]
    db = Database.open(url)
    ids: list[str] = []
    try:
        with db.sessions.begin() as session:
            teams = {name: Team(name=name) for name in dict.fromkeys(t for t, *_ in runs)}
            session.add_all(teams.values())
            session.flush()
            for team, state, minutes, values in runs:
                ids.append(secrets.token_hex(16))
                session.add(Run(
                    id=ids[-1], team_id=teams[team].id, track="1-on", phase="minival",
                    method=team, sensors=["goal"], maps={}, order=list(range(8)), state=state,
                    created_at=start, finished_at=start + dt.timedelta(minutes=minutes),
                    summary=summarize(_records(values), "ppl"),
                ))  # fmt: skip
        with db.sessions() as session:
            board = queries.leaderboards(session, challenge, start + dt.timedelta(days=1))[0]
            from multion.leaderboard.cli import run_rows, shown_rows

            exported = [r["run_id"] for r in shown_rows(session, challenge, run_rows(session))
                        if (r["track"], r["phase"]) == ("1-on", "minival")]  # fmt: skip
    finally:
        db.close()
    by_team = {row.team: row for row in board.rows}
    assert [row.team for row in board.rows] == ["early", "mixed", "late", "low"]
    assert [row.rank for row in board.rows] == [1, 1, 1, 4]
    assert by_team["mixed"].run_id == ids[4]  # finished before ended, then the earliest
    assert exported == [row.run_id for row in board.rows]  # export --best: same runs, same order
