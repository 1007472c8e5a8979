"""The organisers' and participants' commands: team and token admin, ``multion submit``,
baselines through the protocol, runs listing, CSV / JSON export, replay."""

from __future__ import annotations

import csv
import datetime as dt
import json
from pathlib import Path
from typing import Any

import pytest

from multion.cli import main
from multion.leaderboard.challenge import load_challenge
from multion.leaderboard.storage import Database
from multion.leaderboard.web.queries import leaderboards


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
    assert code == 0 and "schema 0003" in out
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
                             "--challenge", str(challenge_file), *db, "--track", "1-on-oracle",
                             "--phase", "minival", "--quiet")  # fmt: skip
    assert code == 0, err
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
        capsys, "leaderboard", "export", *db, "--best", "--out", str(tmp_path / "best.json")
    )
    best = json.loads((tmp_path / "best.json").read_text())["runs"]
    assert code == 0 and all(len(r["episode_records"]) == r["episodes"] for r in best)
    # exactly the runs the leaderboard page shows: one per team, one per baseline method
    db_ = Database.open(database)
    with db_.sessions() as session:
        boards = leaderboards(session, load_challenge(challenge_file), dt.datetime(9999, 1, 1, tzinfo=dt.timezone.utc))
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
    from multion.leaderboard.bench import run_leaderboard_bench

    result = run_leaderboard_bench(size=16, steps=20, verbose=False, rooms=1)
    assert result["session_sps"] > 0 and result["run_sps"] > 0
    assert result["ratio"] == pytest.approx(result["run_sps"] / result["session_sps"])
