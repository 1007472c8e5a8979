"""Issue 53 item 3: counts that add up. A run that played one episode, none (abandoned at
once) or part of one (refunded when the server broke it) is counted as such by ``multion
leaderboard replay``, by its ``RunStatus.episodes_done``, by ``multion leaderboard runs`` (no
score for a refunded run, as the pages) and by ``export`` (the page's "1 / 4" completed)."""

from __future__ import annotations

import csv
import datetime as dt
import json
from pathlib import Path
from typing import Any

import pytest

from multion.leaderboard.challenge import Challenge
from multion.leaderboard.challenge_file import load_challenge, write_challenge
from multion.leaderboard.hidden import HiddenEpisodes, RunDraw
from multion.leaderboard.models import EpisodeRecord, Run, Team
from multion.leaderboard.results import missed_metrics, summarize
from multion.leaderboard.run_store import describe_run
from multion.leaderboard.storage import Database
from multion.leaderboard.web.queries import leaderboards
from multion_agents.bench.pages import bench_challenge
from multion_agents.cli import main
from multion_client.run import describe_run as describe_status
from multion_client.run_protocol import RunStatus

EPISODES = 4
ENDED = dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc)
RUNS = {  # run id: (state, end reason, refunded, actions of the episodes played before the end)
    "oneplayed": ("ended", "abandoned", False, ["0"]),
    "noneplayed": ("ended", "abandoned", False, []),
    "refunded": ("failed", "server_error", True, []),
    "allplayed": ("finished", None, False, ["0", "0", "0", "0"]),
}
"""Each played episode calls FOUND at its first step (a wrong found: it ends there). The
refunded run's 94 steps of its first episode are, as the server stores them, not played."""


@pytest.fixture(scope="module")
def stored(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str, Challenge]:
    """A one-track challenge of 4-episode phases and a database of the runs of RUNS, their
    episodes recorded as the server records them."""
    directory = tmp_path_factory.mktemp("counts")
    path = write_challenge(bench_challenge(EPISODES, (("1-on", 1),)), directory / "c.toml")
    challenge, url = load_challenge(path), f"sqlite:///{directory / 'results.db'}"
    track = challenge.tracks[0]
    phase = track.phases[0]
    hidden = HiddenEpisodes(challenge, in_subprocess=False)
    db = Database.open(url)
    try:
        with db.sessions.begin() as session:
            team = Team(name="counters")
            session.add(team)
            session.flush()
            for run_id, (state, end_reason, refunded, played) in RUNS.items():
                order = list(range(EPISODES))
                ids = hidden.episode_ids(track, phase, RunDraw(run_id, "fixed", tuple(order)))
                records = [_record(run_id, p, ids[p], played[p] if p < len(played) else None)
                           for p in range(EPISODES)]  # fmt: skip
                session.add_all(records)
                session.add(Run(
                    id=run_id, team_id=team.id, track=track.name, phase=phase.name,
                    method=run_id, sensors=["goal"], maps={}, order=order, state=state,
                    end_reason=end_reason, refunded=refunded, created_at=ENDED, finished_at=ENDED,
                    summary=summarize([r.metrics for r in records], track.metric),
                ))  # fmt: skip
    finally:
        db.close()
    return path, url, challenge


def _record(run_id: str, position: int, episode_id: str, actions: str | None) -> EpisodeRecord:
    reason = "not_played" if actions is None else "wrong_found"
    metrics = missed_metrics(1, reason)
    if actions is not None:
        metrics.update(steps=1, wrong_founds=1, ppl=0.25 * (position + 1))
    return EpisodeRecord(
        run_id=run_id, position=position, episode_index=position, episode_id=episode_id,
        end_reason=reason, metrics=metrics, actions=actions or "", seconds=0.0,
    )  # fmt: skip


def _cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out + err


def test_replay_counts_the_episodes_it_played(
    stored: tuple[Path, str, Challenge], capsys: pytest.CaptureFixture[str]
) -> None:
    path, url, _ = stored
    said = {}
    for run_id in RUNS:
        _, said[run_id] = _cli(capsys, "leaderboard", "replay", run_id, "--database", url,
                               "--challenge", str(path))  # fmt: skip
    assert (
        "1 of 4 episodes replayed (1 step); 3 not played (stored as failures)" in said["oneplayed"]
    )
    assert "0 of 4 episodes replayed (0 steps); 4 not played" in said["noneplayed"]
    assert "0 of 4 episodes replayed (0 steps); 4 not played" in said["refunded"]
    assert "(refunded: the pages show no score)" in said["refunded"]
    assert "4 of 4 episodes replayed (4 steps); ppl" in said["allplayed"]
    assert "not played" not in said["allplayed"] and "refunded" not in said["oneplayed"]


def test_run_status_counts_the_episodes_completed(stored: tuple[Path, str, Challenge]) -> None:
    _, url, challenge = stored
    db = Database.open(url)
    try:
        with db.sessions() as session:
            runs = {run_id: session.get(Run, run_id) for run_id in RUNS}
            done = {
                run_id: describe_run(session, challenge, run).episodes_done
                for run_id, run in runs.items()
                if run is not None
            }
    finally:
        db.close()
    assert done == {"oneplayed": 1, "noneplayed": 0, "refunded": 0, "allplayed": 4}


def test_runs_and_export_count_as_the_pages(
    stored: tuple[Path, str, Challenge], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    path, url, challenge = stored
    _, out = _cli(capsys, "leaderboard", "runs", "--database", url)
    lines = {line.split("  ")[0]: line for line in out.strip().splitlines()}
    assert lines["refunded"].endswith(
        "failed (server_error), refunded  0/4 episodes completed  ppl –"
    )
    assert lines["noneplayed"].endswith("0/4 episodes completed  ppl –")  # as the team page
    assert lines["oneplayed"].endswith("1/4 episodes completed  ppl 6.2%")
    assert lines["allplayed"].endswith("4/4 episodes completed  ppl 62.5%")
    for suffix in ("csv", "json"):
        out_file = tmp_path / f"best.{suffix}"
        _cli(capsys, "leaderboard", "export", "--database", url, "--best", "--challenge",
             str(path), "--out", str(out_file))  # fmt: skip
        rows: list[dict[str, Any]] = (
            list(csv.DictReader(out_file.open())) if suffix == "csv"
            else json.loads(out_file.read_text())["runs"]
        )  # fmt: skip
        db = Database.open(url)
        try:
            with db.sessions() as session:
                page = {r.run_id: (r.completed, r.total)
                        for b in leaderboards(session, challenge, ENDED) for r in b.rows}  # fmt: skip
        finally:
            db.close()
        exported = {r["run_id"]: (int(r["episodes_completed"]), int(r["episodes"])) for r in rows}
        assert exported == page == {"allplayed": (4, 4)}
    _cli(capsys, "leaderboard", "export", "--database", url, "--out", str(tmp_path / "all.csv"))
    every = {
        r["run_id"]: r["episodes_completed"] for r in csv.DictReader((tmp_path / "all.csv").open())
    }
    assert every == {"oneplayed": "1", "noneplayed": "0", "refunded": "0", "allplayed": "4"}


def test_the_end_of_submit_says_the_episodes_completed_and_a_refund() -> None:
    def status(state: str, done: int, refunded: bool = False) -> RunStatus:
        return RunStatus("r1", "1-on", "minival", "m", state, None, EPISODES, done, 3, False, 9,
                         "2026-01-01T00:00:00+00:00", None, refunded, False)  # fmt: skip

    assert "r1: finished, 4/4 episodes completed" in describe_status(status("finished", 4))
    refunded = describe_status(status("failed", 0, refunded=True))
    assert "0/4 episodes completed" in refunded and "refunded, not counted in the quota" in refunded
