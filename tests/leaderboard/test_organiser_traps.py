"""The organisers' commands do not mislead: a past seal is said, ``export --best`` is the page,
filters that match nothing name what exists, team names are letters of any script and unique
whatever their case, and a run that played nothing is no leaderboard entry."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import logging
import secrets
from pathlib import Path
from typing import Any

import pytest
from fastapi import FastAPI

from multion.leaderboard.app import check_leaderboard
from multion.leaderboard.challenge import Challenge
from multion.leaderboard.challenge_file import load_challenge, replace_phase, write_challenge
from multion.leaderboard.models import Run, Team
from multion.leaderboard.results import summarize
from multion.leaderboard.settings import LeaderboardSettings
from multion.leaderboard.storage import Database
from multion.leaderboard.web.queries import leaderboards
from multion_agents.cli import main

START = dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc)


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def db_url(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    for name in ("MULTION_LEADERBOARD_DATABASE", "MULTION_LEADERBOARD_CHALLENGE"):
        monkeypatch.delenv(name, raising=False)
    url = f"sqlite:///{tmp_path / 'results.db'}"
    Database.open(url).close()
    return url


def _records(ppl: float, reasons: list[str]) -> list[dict[str, Any]]:
    return [{"ppl": ppl, "progress": ppl, "success": ppl, "spl": ppl, "end_reason": r}
            for r in reasons]  # fmt: skip


def _add_runs(url: str, runs: list[tuple[str, str, str, str, list[dict[str, Any]]]]) -> list[str]:
    """(team, track, phase, state, records) → stored ended runs; returns their ids."""
    ids = []
    db = Database.open(url)
    try:
        with db.sessions.begin() as session:
            teams: dict[str, Team] = {}
            for minutes, (team, track, phase, state, records) in enumerate(runs):
                if team not in teams:
                    teams[team] = Team(name=team)
                    session.add(teams[team])
                    session.flush()
                ids.append(secrets.token_hex(16))
                session.add(Run(
                    id=ids[-1], team_id=teams[team].id, track=track, phase=phase, method=team,
                    sensors=["goal"], maps={}, order=list(range(len(records))), state=state,
                    created_at=START, finished_at=START + dt.timedelta(minutes=minutes),
                    summary=summarize(records, "ppl"),
                ))  # fmt: skip
    finally:
        db.close()
    return ids


def test_a_past_seal_is_said_by_check_tracks_and_serve(
    challenge_file: Path, challenge: Challenge, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    caplog: pytest.LogCaptureFixture,
) -> None:  # fmt: skip
    code, out, _ = run_cli(capsys, "leaderboard", "check", "--challenge", str(challenge_file))
    assert code == 0 and "2 tracks, 4 phases: OK" in out and "warning" not in out
    sealed = challenge.tracks[1].phases[1]
    assert sealed.sealed_until == dt.datetime(2999, 1, 1, tzinfo=dt.timezone.utc)
    past_seal = dataclasses.replace(
        sealed, sealed_until=dt.datetime(2001, 1, 1, tzinfo=dt.timezone.utc)
    )
    past = write_challenge(  # a wrong year: 2001 for 2999
        replace_phase(challenge, "1-on-oracle", past_seal), tmp_path / "past.toml"
    )
    code, out, _ = run_cli(capsys, "leaderboard", "check", "--challenge", str(past))
    assert code == 0
    assert (
        "warning: phase 1-on-oracle/test-challenge: sealed_until 2001-01-01T00:00:00+00:00 is in the past"
        in out
    )
    code, out, _ = run_cli(capsys, "leaderboard", "tracks", "--challenge", str(past))
    assert "sealed until 2001-01-01T00:00:00+00:00 (passed: results shown to everyone)" in out
    track = challenge.tracks[0]  # one track, one phase: no "1 tracks"
    alone = dataclasses.replace(
        challenge, tracks=(dataclasses.replace(track, phases=track.phases[:1]),)
    )
    one = write_challenge(alone, tmp_path / "one.toml")
    code, out, _ = run_cli(capsys, "leaderboard", "check", "--challenge", str(one))
    assert code == 0 and "1 track, 1 phase: OK" in out
    with caplog.at_level(logging.WARNING, logger="multion.leaderboard"):
        settings = LeaderboardSettings(challenge=past, database=f"sqlite:///{tmp_path / 'x.db'}")
        check_leaderboard(FastAPI(), settings)
    assert "1-on-oracle/test-challenge: sealed_until 2001-01-01" in caplog.text


def test_export_best_is_the_page_without_sealed_or_empty_runs(
    db_url: str, challenge_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    played = _records(0.5, ["success", "max_steps"])
    ids = _add_runs(db_url, [
        ("Lab", "1-on", "minival", "finished", played),
        ("Lab", "1-on-oracle", "test-challenge", "finished", played),  # sealed until 2999
        ("Quitters", "1-on", "minival", "ended", _records(0.0, ["abandoned", "not_played"])),
        ("Quitters", "1-on", "minival", "ended", _records(0.0, ["not_played"] * 2)),
        ("Half", "1-on", "minival", "ended", _records(0.0, ["success", "not_played"])),
    ])  # fmt: skip
    db = ["--database", db_url]
    out_file = tmp_path / "best.json"
    code, _, err = run_cli(capsys, "leaderboard", "export", *db, "--best", "--out", str(out_file))
    assert code == 2 and "--challenge" in err and not out_file.exists()
    code, out, _ = run_cli(capsys, "leaderboard", "export", *db, "--best", "--out", str(out_file),
                           "--challenge", str(challenge_file))  # fmt: skip
    best = json.loads(out_file.read_text())["runs"]
    assert code == 0 and "wrote 2 runs" in out
    assert [r["run_id"] for r in best] == [ids[0], ids[4]]  # the page's order
    challenge = load_challenge(challenge_file)
    database = Database.open(db_url)
    with database.sessions() as session:
        boards = leaderboards(session, challenge, START + dt.timedelta(days=1))
    database.close()
    board = next(b for b in boards if (b.track.name, b.phase.name) == ("1-on", "minival"))
    assert [(r.team, r.completed, r.total) for r in board.rows] == [("Lab", 2, 2), ("Half", 1, 2)]
    # everything is still exported without --best
    code, out, _ = run_cli(capsys, "leaderboard", "export", *db, "--out", str(tmp_path / "a.csv"))
    assert code == 0 and "wrote 5 runs" in out


def test_filters_that_match_nothing_name_what_exists(
    db_url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    _add_runs(db_url, [("Lab", "1-on", "minival", "finished", _records(0.5, ["success"]))])
    db = ["--database", db_url]
    code, _, err = run_cli(capsys, "leaderboard", "runs", *db, "--phase", "nosuch")
    assert code == 2 and "--phase 'nosuch': no such phase; phases with runs: minival" in err
    code, _, err = run_cli(capsys, "leaderboard", "runs", *db, "--track", "9-on")
    assert code == 2 and "tracks with runs: 1-on" in err
    code, _, err = run_cli(capsys, "leaderboard", "runs", *db, "--team", "Nobody")
    assert code == 2 and "teams: Lab" in err
    code, _, err = run_cli(capsys, "leaderboard", "runs", *db, "--state", "done")
    assert code == 2 and "states are running, finished, ended, failed" in err
    code, out, _ = run_cli(capsys, "leaderboard", "runs", *db, "--phase", "minival")
    assert code == 0 and "Lab" in out
    code, out, _ = run_cli(capsys, "leaderboard", "runs", *db, "--state", "failed")
    assert code == 0 and out.strip() == "no runs"  # a real filter that matches nothing


def test_team_names_any_script_unique_whatever_the_case(
    db_url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    db = ["--database", db_url]
    for name in ("Très Bien", "Zürich NLP", "東京 lab", "दल"):
        code, out, err = run_cli(capsys, "leaderboard", "team", "add", name, *db)
        assert code == 0 and out.strip().splitlines()[-1].startswith("mlb_"), err
    for clash, existing in (("TRÈS BIEN", "Très Bien"), ("zürich nlp", "Zürich NLP")):
        code, _, err = run_cli(capsys, "leaderboard", "team", "add", clash, *db)
        assert code == 2 and "already exists" in err and f"by case alone: {existing!r}" in err
    decomposed = "Tre\u0300s Bien"  # the same name typed with a combining accent
    code, _, err = run_cli(capsys, "leaderboard", "team", "add", decomposed, *db)
    assert code == 2 and "already exists" in err
    code, _, err = run_cli(capsys, "leaderboard", "token", "add", "très bien", *db)
    assert code == 2 and "did you mean 'Très Bien'?" in err
    code, out, _ = run_cli(capsys, "leaderboard", "token", "add", decomposed, *db)
    assert code == 0 and out.startswith("mlb_")
    for bad in ("_x", "trailing ", "tab\there", "a" * 81, "semi;colon"):
        code, _, err = run_cli(capsys, "leaderboard", "team", "add", bad, *db)
        assert code == 2 and "letters (of any script)" in err
    code, out, _ = run_cli(capsys, "leaderboard", "team", "list", *db)
    assert [line.split("\t")[0] for line in out.strip().splitlines()] == sorted(
        ["Très Bien", "Zürich NLP", "東京 lab", "दल"]
    )
