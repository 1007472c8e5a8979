"""``multion bench --only leaderboard``: the per-step cost of a run versus a plain session.

One local server with a leaderboard (a temporary challenge and SQLite database) serves both:
a plain session (``RemoteEnv``) playing the run's hidden episodes inline, and a run
(``RunEnv``: token check, sequence numbers, the state saved in the database at every step,
answers filtered to the track's sensors). Steps alternate between the two in short blocks so
background load hits both alike; only steps are timed. Target: run / session ≥ 0.9.
"""

from __future__ import annotations

import secrets
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from multion.api.local_server import LocalServer
from multion.leaderboard.challenge import (
    Challenge,
    HiddenScenes,
    Limits,
    Phase,
    Track,
)
from multion.leaderboard.challenge_file import load_challenge, write_challenge
from multion.leaderboard.cli_serve import SERVE_MODULE
from multion.leaderboard.hidden import generate_hidden_episodes
from multion.leaderboard.storage import Database, add_team
from multion_client.env import RemoteEnv
from multion_client.run import RunEnv

BLOCK_STEPS = 5
TARGET = 0.9


def bench_challenge(size: int, rooms: int) -> Challenge:
    """One 3-ON track at ``size``² in houses of ``rooms`` rooms, a fresh secret; its minival
    phase plays a fixed set, so that the session plays the same episodes inline."""
    return Challenge(
        name="bench",
        secret=secrets.token_urlsafe(24),
        limits=Limits(step_timeout_s=600),
        hidden=HiddenScenes(rooms=(rooms, rooms)),
        tracks=(
            Track("3-on", num_goals=3, camera={"width": size, "height": size}, phases=(
                Phase("minival", episodes=4, houses=1, episodes_per_run="fixed"),
            )),
        ),
    )  # fmt: skip


def run_leaderboard_bench(
    size: int = 256,
    steps: int = 300,
    server_options: list[str] | None = None,
    verbose: bool = True,
    rooms: int = 3,
) -> dict[str, Any]:
    """Print and return steps/s of a session and of a run at ``size``² RGB-D, and their ratio
    (in one hidden house of ``rooms`` rooms)."""
    with tempfile.TemporaryDirectory(prefix="multion-bench-") as directory:
        path = write_challenge(bench_challenge(size, rooms), Path(directory) / "challenge.toml")
        challenge = load_challenge(path)
        track = challenge.tracks[0]
        episodes = generate_hidden_episodes(challenge, track, track.phases[0])
        database = f"sqlite:///{Path(directory) / 'bench.db'}"
        db = Database.open(database)
        with db.sessions.begin() as session:
            token = add_team(session, "bench")[1]
        db.close()
        options = ["--challenge", str(path), "--database", database, *(server_options or [])]
        with LocalServer(workers=1, options=options, serve_module=SERVE_MODULE) as server:
            sensors = ["rgb", "depth", "goal"]
            config = {
                **track.env_config(track.phases[0], tuple(sensors)),
                "episodes": [e.to_dict() for e in episodes],
            }
            session_env = RemoteEnv(server.url, config)
            run_env = RunEnv(server.url, "3-on", "minival", "bench", token=token, sensors=sensors)
            try:
                timed = {"session": 0.0, "run": 0.0}
                done_steps = {"session": 0, "run": 0}
                envs: dict[str, RemoteEnv | RunEnv] = {"session": session_env, "run": run_env}
                rng = np.random.default_rng(0)
                session_env.reset(options={"episode_index": 0})
                run_env.reset()
                while min(done_steps.values()) < steps:
                    for name, env in envs.items():
                        for _ in range(BLOCK_STEPS):
                            action = int(rng.choice([1, 1, 2, 3]))  # never FOUND
                            begin = time.perf_counter()
                            _, _, terminated, truncated, _ = env.step(action)
                            timed[name] += time.perf_counter() - begin
                            done_steps[name] += 1
                            if terminated or truncated:
                                env.reset()
            finally:
                session_env.close()
                run_env.abandon()
                run_env.close()
    rates = {name: done_steps[name] / timed[name] for name in timed}
    ratio = rates["run"] / rates["session"]
    extra_ms = 1000 / rates["run"] - 1000 / rates["session"]
    if verbose:
        print(
            f"\nLeaderboard run vs plain session, one env over HTTP, {size}² RGB-D, {steps} steps each"
        )
        print(
            f"{'session':>10} {'run':>8} {'run/session':>12} {'run extra ms/step':>18}  (target ≥ {TARGET})"
        )
        print(f"{rates['session']:>10.1f} {rates['run']:>8.1f} {ratio:>12.2f} {extra_ms:>18.2f}")
    return {
        "session_sps": rates["session"],
        "run_sps": rates["run"],
        "ratio": ratio,
        "extra_ms_per_step": extra_ms,
        "size": size,
    }
