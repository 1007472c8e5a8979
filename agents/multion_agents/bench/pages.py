"""``multion bench --only pages``: the leaderboard page's server time with many stored runs.

A temporary SQLite results database gets ``runs`` finished runs (spread over 3 tracks × 2
phases and 50 teams), each with ``episodes`` per-episode records and its aggregates, as real
runs store them. The app is driven in-process (FastAPI's TestClient: the whole server stack
but the network), and each page is fetched ``repeats`` times after one warm-up request.
Target: the leaderboard page in under 100 ms (it reads one row per run, never episodes).
"""

from __future__ import annotations

import datetime as dt
import secrets
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion.leaderboard.app import LeaderboardExtension
from multion.leaderboard.challenge import Challenge, HiddenScenes, Phase, Track
from multion.leaderboard.challenge_file import write_challenge
from multion.leaderboard.models import EpisodeRecord, Run, Team
from multion.leaderboard.results import summarize
from multion.leaderboard.settings import LeaderboardSettings
from multion.leaderboard.storage import Database

TARGET_MS = 100.0
TRACKS = (("1-on", 1), ("2-on", 2), ("3-on", 3))
PHASES = ("minival", "test-standard")


def bench_challenge(episodes: int, tracks: tuple[tuple[str, int], ...] = TRACKS) -> Challenge:
    """The bench's challenge: each of ``tracks`` (name, goals) with a minival and a
    test-standard phase of ``episodes`` episodes, a fresh secret."""
    return Challenge(
        name="bench",
        secret=secrets.token_urlsafe(24),
        hidden=HiddenScenes(rooms=(1, 1)),
        tracks=tuple(
            Track(
                name,
                num_goals=m,
                camera={"width": 32, "height": 32},
                phases=(
                    Phase("minival", episodes=episodes, houses=1, feedback="episodes"),
                    Phase("test-standard", episodes=episodes, houses=1),
                ),
            )  # fmt: skip
            for name, m in tracks
        ),
    )


def fill_database(url: str, runs: int, episodes: int, seed: int = 0) -> list[str]:
    """Insert ``runs`` finished runs with ``episodes`` records each; returns their ids."""
    rng = np.random.default_rng(seed)
    db = Database.open(url)
    start = dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc)
    ids = []
    try:
        with db.sessions.begin() as session:
            teams = [Team(name=f"team-{k:02d}") for k in range(50)]
            session.add_all(teams)
            session.flush()
            for k in range(runs):
                (track, m), phase = TRACKS[k % 3], PHASES[(k // 3) % 2]
                skill = float(rng.uniform(0.05, 0.9))
                records = [_episode(rng, m, skill) for _ in range(episodes)]
                run = Run(
                    id=secrets.token_hex(16), team_id=teams[k % 50].id, track=track, phase=phase,
                    method=f"method {k % 7}", sensors=["rgb", "depth", "goal"], maps={},
                    order=list(range(episodes)), state="finished",
                    created_at=start + dt.timedelta(hours=k),
                    finished_at=start + dt.timedelta(hours=k, minutes=30),
                    summary=summarize(records, "ppl"),
                )  # fmt: skip
                session.add(run)
                session.add_all(
                    EpisodeRecord(
                        run_id=run.id,
                        position=i,
                        episode_index=i,
                        episode_id=f"e{i}",
                        end_reason=r["end_reason"],
                        metrics=r,
                        actions="1" * r["steps"],
                    )  # fmt: skip
                    for i, r in enumerate(records)
                )
                ids.append(run.id)
    finally:
        db.close()
    return ids


def _episode(rng: np.random.Generator, m: int, skill: float) -> dict[str, Any]:
    found = int(rng.binomial(m, skill))
    success = float(found == m)
    steps = int(rng.integers(50, 500))
    return {
        "steps": steps, "goals_found": found, "progress": found / m, "success": success,
        "spl": success * float(rng.uniform(0.5, 1.0)), "ppl": found / m * float(rng.uniform(0.5, 1)),
        "seen_before_current": [bool(b) for b in rng.integers(0, 2, size=m - 1)],
        "end_reason": "success" if success else "max_steps",
    }  # fmt: skip


def run_pages_bench(
    runs: int = 1000, episodes: int = 30, repeats: int = 20, verbose: bool = True
) -> dict[str, float]:
    """Median and 95th-percentile server milliseconds per page; prints them with the target."""
    from fastapi.testclient import TestClient

    with tempfile.TemporaryDirectory(prefix="multion-pages-bench-") as directory:
        challenge = write_challenge(bench_challenge(episodes), Path(directory) / "challenge.toml")
        url = f"sqlite:///{Path(directory) / 'results.db'}"
        started = time.perf_counter()
        ids = fill_database(url, runs, episodes)
        if verbose:
            print(
                f"pages bench: {runs} runs × {episodes} episodes stored in "
                f"{time.perf_counter() - started:.1f} s"
            )
        app = create_app(
            ServerSettings(workers=1),
            [
                LeaderboardExtension(
                    LeaderboardSettings(
                        challenge=challenge, database=url, warm_up=False, draw_pictures=False
                    )
                )
            ],
        )
        pages = {
            "leaderboard": "/leaderboard",
            "team": "/leaderboard/teams/team-07",
            "run (test-standard)": f"/leaderboard/runs/{ids[3]}",
            "rules": "/leaderboard/rules",
        }
        result: dict[str, float] = {}
        with TestClient(app) as client:
            for name, path in pages.items():
                assert client.get(path).status_code == 200, path
                times = []
                for _ in range(repeats):
                    begin = time.perf_counter()
                    answer = client.get(path)
                    times.append(1000 * (time.perf_counter() - begin))
                    assert answer.status_code == 200
                times.sort()
                result[f"{name} median ms"] = statistics.median(times)
                result[f"{name} p95 ms"] = times[min(len(times) - 1, int(0.95 * len(times)))]
    if verbose:
        print(f"{'page':22s} {'median ms':>10s} {'p95 ms':>8s}")
        for name in pages:
            print(f"{name:22s} {result[f'{name} median ms']:10.1f} {result[f'{name} p95 ms']:8.1f}")
        ratio = TARGET_MS / result["leaderboard median ms"]
        print(f"leaderboard page: target {TARGET_MS:.0f} ms / median = {ratio:.2f} (≥ 1 meets it)")
    return result
