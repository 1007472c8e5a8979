"""``multion bench --only lanes``: a phase played with one lane and with two, on a server with
two simulator workers: the wall time of the whole run, and their ratio (target ≥ 1.6).

The client only sends random moves (never FOUND, so every episode lasts ``max_steps``): the
bench measures what the server can do in parallel, not an agent's thinking time.
"""

from __future__ import annotations

import os
import secrets
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from multion.api.local_server import LocalServer
from multion.leaderboard.challenge import Challenge, HiddenScenes, Limits, Phase, Track
from multion.leaderboard.challenge_file import write_challenge
from multion.leaderboard.cli_serve import SERVE_MODULE
from multion.leaderboard.storage import Database, add_team
from multion_client.run import RunEnv

TARGET = 1.6


def bench_challenge(size: int, episodes: int, max_steps: int, rooms: int) -> Challenge:
    """One 3-ON track at ``size``² in houses of ``rooms`` rooms, runs of up to two lanes, a
    fresh secret."""
    return Challenge(
        name="bench-lanes",
        secret=secrets.token_urlsafe(24),
        limits=Limits(step_timeout_s=600, max_envs_per_run=2),
        hidden=HiddenScenes(rooms=(rooms, rooms)),
        tracks=(
            Track("3-on", num_goals=3, camera={"width": size, "height": size},
                  max_steps=max_steps, phases=(
                Phase("test", episodes=episodes, houses=2, feedback="aggregate"),
            )),
        ),
    )  # fmt: skip


def bench_server_options(
    directory: Path, teams: list[str], size: int, episodes: int, max_steps: int, rooms: int
) -> tuple[list[str], list[str]]:
    """Write the bench's challenge file and SQLite database (``teams`` added, without quotas)
    into ``directory``: the server's options and each team's token."""
    challenge = bench_challenge(size, episodes, max_steps, rooms)
    path = write_challenge(challenge, directory / "challenge.toml")
    database = f"sqlite:///{directory / 'bench.db'}"
    db = Database.open(database)
    with db.sessions.begin() as session:
        tokens = [add_team(session, name)[1] for name in teams]
    db.close()
    return ["--challenge", str(path), "--database", database], tokens


def play_lane(env: RunEnv, seed: int) -> int:
    """Play a lane to its end with random moves; returns its steps."""
    rng = np.random.default_rng(seed)
    steps = 0
    while not env.run_done:
        env.reset()
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(int(rng.choice([1, 1, 2, 3])))
            done, steps = terminated or truncated, steps + 1
    return steps


def timed_run(url: str, token: str, lanes: int) -> tuple[float, int]:
    """Wall seconds and steps of one whole run played with ``lanes`` lanes."""
    begin = time.perf_counter()
    envs = RunEnv.lanes(url, "3-on", "test", f"bench x{lanes}", token=token,
                        sensors=["rgb", "depth", "goal"], num_envs=lanes)  # fmt: skip
    counts = [0] * lanes

    def play(k: int) -> None:
        counts[k] = play_lane(envs[k], seed=k)

    threads = [threading.Thread(target=play, args=(k,)) for k in range(lanes)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    seconds = time.perf_counter() - begin
    status = envs[0].status()
    assert status.state == "finished", status
    for env in envs:
        env.close()
    return seconds, sum(counts)


def run_lanes_bench(
    size: int = 256, episodes: int = 40, max_steps: int = 50, rooms: int = 3, verbose: bool = True
) -> dict[str, Any]:
    """Print and return the wall time of a run with one lane and with two, and their ratio."""
    with tempfile.TemporaryDirectory(prefix="multion-bench-") as directory:
        options, (token,) = bench_server_options(
            Path(directory), ["baselines"], size, episodes, max_steps, rooms
        )
        with LocalServer(workers=2, options=options, serve_module=SERVE_MODULE) as server:
            timed_run(server.url, token, 2)  # warm up: houses built, workers' scenes loaded
            one, steps_one = timed_run(server.url, token, 1)
            two, steps_two = timed_run(server.url, token, 2)
    ratio = one / two
    if verbose:
        load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
        print(f"\nA {episodes}-episode run ({max_steps} steps each, {size}² RGB-D) on 2 simulator "
              f"workers (load average {load})")  # fmt: skip
        print(f"{'lanes':>6} {'seconds':>9} {'steps/s':>9}")
        print(f"{1:>6} {one:>9.1f} {steps_one / one:>9.1f}")
        print(f"{2:>6} {two:>9.1f} {steps_two / two:>9.1f}")
        print(f"1 lane / 2 lanes wall time: {ratio:.2f} (target ≥ {TARGET})")
    return {"one_lane_s": one, "two_lanes_s": two, "ratio": ratio, "steps": steps_one}
