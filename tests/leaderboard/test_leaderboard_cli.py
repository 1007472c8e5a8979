"""The organisers' and participants' commands: team and token admin, ``multion submit``,
baselines through the protocol, runs listing, CSV / JSON export, replay."""

from __future__ import annotations

import csv
import datetime as dt
import json
import sqlite3
from pathlib import Path
from typing import Any

import pytest

from multion.leaderboard.challenge_file import load_challenge
from multion.leaderboard.storage import Database
from multion.leaderboard.web.queries import leaderboards
from multion_agents.cli import main


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_admin_submit_baselines_export_replay(
    server: Any,
    database: str,
    challenge_file: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    db = ["--database", database]
    code, out, _ = run_cli(capsys, "leaderboard", "init", *db)
    assert code == 0 and "schema 0005" in out
    code, out, _ = run_cli(capsys, "leaderboard", "tracks", "--challenge", str(challenge_file))
    assert code == 0 and "minival: 3 episodes" in out and "1 total" in out
    code, out, _ = run_cli(capsys, "leaderboard", "team", "add", "Lab One", *db)
    token = out.strip().splitlines()[-1]
    assert code == 0 and token.startswith("mlb_")
    code, _, err = run_cli(capsys, "leaderboard", "team", "add", "Lab One", *db)
    assert code == 2 and "already exists" in err

    # a participant submits with the token in the environment
    monkeypatch.setenv("MULTION_TOKEN", token)
    code, out, _ = run_cli(capsys, "submit", "--server", server.url, "--track", "1-on",
                           "--phase", "minival", "--agent", "random", "--method", "Rand", "--quiet")  # fmt: skip
    assert code == 0 and "finished" in out and "ppl" in out
    code, _, err = run_cli(capsys, "submit", "--server", server.url, "--track", "1-on",
                           "--phase", "minival", "--agent", "oracle-planner", "--quiet")  # fmt: skip
    assert code == 2 and "oracle_map" in err  # a standard track does not allow it

    # baselines on the oracle track's minival, through the same protocol
    code, out, err = run_cli(capsys, "leaderboard", "baselines", "--server", server.url,
                             *db, "--track", "1-on-oracle", "--phase", "minival", "--quiet")  # fmt: skip
    assert code == 0, err
    # --quiet drops the progress bars, not the news: each run's start and end, then a count
    assert out.count("1-on-oracle/minival: ") == 4 and out.count("  finished: ppl ") == 4
    assert out.strip().endswith("4 baseline runs played")
    code, out, _ = run_cli(capsys, "leaderboard", "runs", *db, "--track", "1-on-oracle")
    names = [line.split("  ")[3] for line in out.strip().splitlines()]
    assert sorted(names) == ["explorer", "oracle-planner", "random", "random-oracle-found"]
    assert all("[baseline]" in line and "finished" in line for line in out.strip().splitlines())

    # export, then replay one run from the database
    code, out, _ = run_cli(capsys, "leaderboard", "export", *db, "--out", str(tmp_path / "all.csv"))
    rows = list(csv.DictReader((tmp_path / "all.csv").open()))
    assert code == 0 and {r["team"] for r in rows} >= {"Lab One", "baselines"}
    assert {"ppl_mean", "ppl_low", "ppl_high", "method", "baseline"} <= set(rows[0])
    code, _, _ = run_cli(
        capsys, "leaderboard", "export", *db, "--best", "--challenge", str(challenge_file),
        "--out", str(tmp_path / "best.json"),
    )  # fmt: skip
    best = json.loads((tmp_path / "best.json").read_text())["runs"]
    assert code == 0 and all(len(r["episode_records"]) == r["episodes"] for r in best)
    # exactly the runs the leaderboard page shows: one per team, one per baseline method
    db_ = Database.open(database)
    with db_.sessions() as session:
        boards = leaderboards(
            session, load_challenge(challenge_file), dt.datetime(9999, 1, 1, tzinfo=dt.timezone.utc)
        )
    db_.close()
    shown = {row.run_id for board in boards for row in board.rows}
    assert {r["run_id"] for r in best} == shown
    assert sum(r["baseline"] for r in best) == 4  # the four baseline methods on 1-on-oracle
    planner = next(r for r in rows if r["method"] == "oracle-planner")
    code, out, _ = run_cli(capsys, "leaderboard", "replay", planner["run_id"], *db,
                           "--challenge", str(challenge_file))  # fmt: skip
    assert code == 0 and "identical to the stored records" in out

    # a revoked token is refused
    code, _, _ = run_cli(capsys, "leaderboard", "token", "revoke", "Lab One", *db)
    assert code == 0
    code, _, err = run_cli(capsys, "submit", "--server", server.url, "--track", "1-on",
                           "--phase", "minival", "--agent", "random", "--quiet")  # fmt: skip
    assert code == 2 and "unauthorized" in err


def test_the_bench_measures_a_run_against_a_session() -> None:
    from multion_agents.bench.leaderboard import run_leaderboard_bench

    result = run_leaderboard_bench(size=16, steps=20, verbose=False, rooms=1)
    assert result["session_sps"] > 0 and result["run_sps"] > 0
    assert result["ratio"] == pytest.approx(result["run_sps"] / result["session_sps"])


READ_ONLY = [
    ["runs"],
    ["team", "list"],
    ["token", "list", "Lab One"],
    ["export", "--out", "results.csv"],
    ["export", "--best", "--out", "results.json"],
    ["replay", "0123abcd"],
    ["baselines", "--server", "http://127.0.0.1:9"],
]


@pytest.mark.parametrize("argv", READ_ONLY, ids=lambda a: " ".join(a[:2]))
def test_commands_never_create_a_database(
    argv: list[str],
    challenge_file: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MULTION_LEADERBOARD_DATABASE", raising=False)
    monkeypatch.setenv("MULTION_LEADERBOARD_CHALLENGE", str(challenge_file))
    code, out, err = run_cli(capsys, "leaderboard", *argv)
    assert code == 2 and "no leaderboard database at" in err
    assert "leaderboard.db" in err and "--database" in err and "MULTION_LEADERBOARD_DATABASE" in err
    assert list(tmp_path.iterdir()) == []  # no database, no empty export
    # a URL given by the variable is named as such
    monkeypatch.setenv("MULTION_LEADERBOARD_DATABASE", f"sqlite:///{tmp_path / 'typo.db'}")
    code, out, err = run_cli(capsys, "leaderboard", *argv)
    assert code == 2 and "typo.db ($MULTION_LEADERBOARD_DATABASE)" in err
    assert list(tmp_path.iterdir()) == []


def test_a_changed_secret_is_refused_by_serve_and_replay(
    launch: Any,
    make_challenge: Any,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    import subprocess
    import sys

    from multion.leaderboard.challenge_file import load_challenge

    database = f"sqlite:///{tmp_path / 'results.db'}"
    first = make_challenge(tmp_path)
    secret = load_challenge(first).secret
    server = launch(first, database)  # stores the secret's fingerprint
    server.stop()
    other_dir = tmp_path / "other"
    other_dir.mkdir()
    other = make_challenge(other_dir)
    other.write_text(other.read_text().replace(secret, "another-secret-0123456789abcdef"))
    done = subprocess.run(
        [sys.executable, "-m", "multion_agents.cli", "serve", "--challenge", str(other),
         "--database", database, "--port", "9"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2, done.stdout + done.stderr
    assert "the challenge secret is not the one this database was used with" in done.stdout
    assert "Traceback" not in done.stdout + done.stderr
    code, _, err = run_cli(capsys, "leaderboard", "replay", "0123abcd", "--database", database,
                           "--challenge", str(other))  # fmt: skip
    assert code == 2 and "the challenge secret is not the one" in err
    # the database keeps the fingerprint, never the secret
    with sqlite3.connect(tmp_path / "results.db") as connection:
        stored = connection.execute("SELECT fingerprint FROM secret_fingerprint").fetchall()
        dump = "\n".join(connection.iterdump())
    assert len(stored) == 1 and len(stored[0][0]) == 64
    assert secret not in dump
    # the original secret still starts
    launch(first, database).stop()
