"""``multion bench --only lanes``: a phase played with one lane and with two (or ``--lanes N``),
on a server with two simulator workers: the wall time of the whole run, and their ratio
(target ≥ 1.6 with two lanes), with the renderer asked for.

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
MAX_LANES = 8
FULL_RUN_STEPS = 1000 * 2500
"""A MultiON 2.0 test phase whose every episode runs to the step limit: the longest it takes."""


def bench_challenge(
    size: int, episodes: int, max_steps: int, rooms: int, renderer: str = "tiny", lanes: int = 2
) -> Challenge:
    """One 3-ON track at ``size``² drawn by ``renderer`` in houses of ``rooms`` rooms, runs of
    up to ``lanes`` lanes, a fresh secret."""
    camera = {"width": size, "height": size, "renderer": renderer}
    return Challenge(
        name="bench-lanes",
        secret=secrets.token_urlsafe(24),
        limits=Limits(step_timeout_s=600, max_envs_per_run=lanes),
        hidden=HiddenScenes(rooms=(rooms, rooms)),
        tracks=(
            Track("3-on", num_goals=3, camera=camera,
                  max_steps=max_steps, phases=(
                Phase("test", episodes=episodes, houses=2, feedback="aggregate"),
            )),
        ),
    )  # fmt: skip


def bench_server_options(
    directory: Path, teams: list[str], challenge: Challenge
) -> tuple[list[str], list[str]]:
    """Write ``challenge`` and an SQLite database (``teams`` added, without quotas) into
    ``directory``: the server's options and each team's token."""
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
    size: int = 256, episodes: int = 40, max_steps: int = 50, rooms: int = 3,
    verbose: bool = True, renderer: str = "tiny", lanes: int = 2,
) -> dict[str, Any]:  # fmt: skip
    """Print and return the wall time of a run with one lane and with ``lanes``, their ratio,
    and the wall time a 1,000-episode run of 2,500-step episodes would take at these rates."""
    if not 2 <= lanes <= MAX_LANES:
        raise ValueError(f"lanes must be in [2, {MAX_LANES}], got {lanes}")
    challenge = bench_challenge(size, episodes, max_steps, rooms, renderer, lanes)
    with tempfile.TemporaryDirectory(prefix="multion-bench-") as directory:
        options, (token,) = bench_server_options(Path(directory), ["baselines"], challenge)
        with LocalServer(workers=2, options=options, serve_module=SERVE_MODULE) as server:
            timed_run(server.url, token, lanes)  # warm up: houses built, workers' scenes loaded
            one, steps_one = timed_run(server.url, token, 1)
            many, steps_many = timed_run(server.url, token, lanes)
    ratio = one / many
    hours = {k: FULL_RUN_STEPS / (steps / seconds) / 3600
             for k, steps, seconds in ((1, steps_one, one), (lanes, steps_many, many))}  # fmt: skip
    if verbose:
        load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
        print(f"\nA {episodes}-episode run ({max_steps} steps each, {size}² RGB-D, {renderer}) on 2 "
              f"simulator workers (load average {load})")  # fmt: skip
        print(f"{'lanes':>6} {'seconds':>9} {'steps/s':>9} {'hours for 1,000 x 2,500 steps':>31}")
        for count, seconds, steps in ((1, one, steps_one), (lanes, many, steps_many)):
            print(f"{count:>6} {seconds:>9.1f} {steps / seconds:>9.1f} {hours[count]:>31.1f}")
        target = f" (target ≥ {TARGET})" if lanes == 2 else ""
        print(f"1 lane / {lanes} lanes wall time: {ratio:.2f}{target}")
    return {"one_lane_s": one, "lanes": lanes, "lanes_s": many, "ratio": ratio,
            "steps": steps_one, "full_run_hours": hours}  # fmt: skip
