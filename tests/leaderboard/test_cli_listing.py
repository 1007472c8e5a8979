"""What the organisers' listing commands print of stored runs (issue 42): ``runs`` says a failed
run was refunded, ``export --best`` has the page's rank and overlap columns, counts of one are
singular."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from stored_runs import StoredRun, store_runs

from multion.leaderboard.challenge_file import write_challenge
from multion.leaderboard.storage import Database
from multion_agents.bench.pages import bench_challenge
from multion_agents.cli import main

VALUES = [0.1, 0.2, 0.3, 0.7, 0.05, 0.6, 0.9, 0.33]


@pytest.fixture
def stored(tmp_path: Path) -> tuple[Path, str, list[str]]:
    """A one-track challenge and a database of four teams' runs: two ranked 1 (equal scores),
    one close behind (overlapping intervals), one far behind, and a refunded failed run."""
    challenge = write_challenge(bench_challenge(8, (("1-on", 1),)), tmp_path / "challenge.toml")
    url = f"sqlite:///{tmp_path / 'results.db'}"
    Database.open(url).close()
    ids = store_runs(url, [
        StoredRun("early", "first method", VALUES, minutes=1),
        StoredRun("late", "same numbers later", VALUES[::-1], minutes=9),
        StoredRun("close", "a little lower", [v * 0.9 for v in VALUES], minutes=3),
        StoredRun("far", "far behind", [0.0] * 7 + [0.01], minutes=2),
        StoredRun("broken", "server broke it", [None] * 8, state="failed",
                  end_reason="server_error", refunded=True, minutes=4),
    ])  # fmt: skip
    return challenge, url, ids


def _cli(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    assert main(list(argv)) == 0
    return capsys.readouterr().out


def test_runs_says_a_failed_run_was_refunded(
    stored: tuple[Path, str, list[str]], capsys: pytest.CaptureFixture[str]
) -> None:
    _, url, ids = stored
    out = _cli(capsys, "leaderboard", "runs", "--database", url, "--state", "failed")
    assert out.startswith(ids[4]) and "failed (server_error), refunded" in out
    out = _cli(capsys, "leaderboard", "runs", "--database", url, "--state", "finished")
    assert "refunded" not in out


def test_export_best_has_the_pages_rank_and_overlap(
    stored: tuple[Path, str, list[str]], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    challenge, url, ids = stored
    out = tmp_path / "best.csv"
    _cli(capsys, "leaderboard", "export", "--database", url, "--best", "--challenge",
         str(challenge), "--out", str(out))  # fmt: skip
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0])[:3] == ["rank", "overlaps_leader", "run_id"]
    shown = [(r["team"], r["rank"], r["overlaps_leader"]) for r in rows]
    assert shown == [("early", "1", "False"), ("late", "1", "False"),
                     ("close", "3", "True"), ("far", "4", "False")]  # fmt: skip
    assert [r["run_id"] for r in rows] == [ids[0], ids[1], ids[2], ids[3]]


def test_tracks_counts_one_house_and_one_episode(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    challenge = write_challenge(bench_challenge(1, (("1-on", 1),)), tmp_path / "challenge.toml")
    out = _cli(capsys, "leaderboard", "tracks", "--challenge", str(challenge))
    assert "minival: 1 episode in 1 house, feedback episodes" in out
