"""``multion bench --only participants``: N participants playing at once, each its own run
through ``RunEnv`` (issue 33): the server's steps per second and the step latency that each
participant sees (percentiles over every step of every participant).

Participants send random moves (never FOUND, so every episode lasts ``max_steps``) from one
thread each, as separate teams on one server with two simulator workers: the bench measures
what the server gives a crowd, not an agent's thinking time.
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from multion.api.local_server import LocalServer
from multion.leaderboard.cli_serve import SERVE_MODULE
from multion_agents.bench.lanes import bench_challenge, bench_server_options
from multion_client.run import RunEnv

MAX_PARTICIPANTS = 64
"""More threads than this only measure the client machine."""


def play_participant(url: str, token: str, name: str, latencies: list[float], seed: int) -> int:
    """Play one run to its end with random moves, recording each step's latency; its steps."""
    rng = np.random.default_rng(seed)
    env = RunEnv(url, "3-on", "test", name, token=token, sensors=["rgb", "depth", "goal"])
    steps = 0
    try:
        while not env.run_done:
            env.reset()
            done = False
            while not done:
                tick = time.perf_counter()
                _, _, terminated, truncated, _ = env.step(int(rng.choice([1, 1, 2, 3])))
                latencies.append(time.perf_counter() - tick)
                done, steps = terminated or truncated, steps + 1
    finally:
        env.close()
    return steps


def run_participants_bench(
    participants: int = 8, size: int = 64, episodes: int = 4, max_steps: int = 25,
    rooms: int = 3, verbose: bool = True, renderer: str = "tiny",
) -> dict[str, Any]:  # fmt: skip
    """Print and return steps/s and step-latency percentiles of ``participants`` at once."""
    if not 1 <= participants <= MAX_PARTICIPANTS:
        raise ValueError(f"participants must be in [1, {MAX_PARTICIPANTS}], got {participants}")
    challenge = bench_challenge(size, episodes, max_steps, rooms, renderer)
    with tempfile.TemporaryDirectory(prefix="multion-bench-") as directory:
        names = [f"participant {k}" for k in range(participants)]
        options, tokens = bench_server_options(Path(directory), names, challenge)
        with LocalServer(workers=2, options=options, serve_module=SERVE_MODULE) as server:
            latencies: list[list[float]] = [[] for _ in range(participants)]
            counts = [0] * participants

            def play(k: int) -> None:
                counts[k] = play_participant(
                    server.url, tokens[k], f"bench p{k}", latencies[k], seed=k
                )

            begin = time.perf_counter()
            threads = [threading.Thread(target=play, args=(k,)) for k in range(participants)]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join()
            seconds = time.perf_counter() - begin
    every = np.asarray([x for per in latencies for x in per]) * 1000
    steps = sum(counts)
    figures: dict[str, Any] = {
        "participants": participants,
        "steps": steps,
        "steps_per_s": steps / seconds,
        **{f"latency_p{q}_ms": float(np.percentile(every, q)) for q in (50, 90, 99)},
    }
    if verbose:
        load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
        print(
            f"\n{participants} participants at once, each a {episodes}-episode run of "
            f"{max_steps}-step episodes ({size}² RGB-D, {renderer}), 2 simulator workers "
            f"(load {load})"
        )
        print(
            f"  {figures['steps_per_s']:.1f} steps/s over {steps} steps; step latency p50 "
            f"{figures['latency_p50_ms']:.0f} ms, p90 {figures['latency_p90_ms']:.0f} ms, "
            f"p99 {figures['latency_p99_ms']:.0f} ms"
        )
    return figures
