"""``multion bench --only env-processes``: memory and frames/s of the local training envs with
one env per simulator process or several (``multion train --envs-per-process``, issue 44).

For each number of envs and envs per process, the v3 recipe's training envs (36² RGB-D, a
25-cell oracle map, online train episodes) are opened as the trainer opens them, reset, and
stepped with the untrained policy's action distribution (FOUND with probability 0.02). It
prints the worker processes' resident memory (RSS summed, which counts the pages they share
once per process, and PSS, which splits them) after the steps, and the steps' frames/s. The
goal-site caches fill as episodes visit houses, so a short run shows the fixed cost of a
process (imports, scenes) more than a long run's caches.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium.vector import AsyncVectorEnv, VectorEnv

from multion_agents.agent import merge_overrides
from multion_agents.learned.env_workers import SharedProcessVectorEnv
from multion_agents.learned.models import model_spec
from multion_agents.learned.rollout_envs import make_vector_env, training_env_config

V3_OVERRIDES: dict[str, dict[str, Any]] = {"maps": {"ego_size": 25}, "task": {"slack_reward": 0.0}}


def _worker_pids(vector: VectorEnv) -> list[int]:
    """This vector env's simulator processes: not the caller's other children (a test
    suite's servers) nor multiprocessing's resource tracker."""
    if isinstance(vector, SharedProcessVectorEnv):
        return vector.worker_pids
    if isinstance(vector, AsyncVectorEnv):
        return [process.pid for process in vector.processes if process.pid is not None]
    raise TypeError(f"{type(vector).__name__} runs no local simulator processes")


def _memory_mib(pids: Sequence[int]) -> tuple[float, float]:
    """(RSS, PSS) of these processes, summed, in MiB (Linux's smaps_rollup)."""
    rss = pss = 0.0
    for pid in pids:
        for row in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            key, _, value = row.partition(":")
            if key in ("Rss", "Pss"):
                kib = float(value.split()[0])
                rss += kib if key == "Rss" else 0.0
                pss += kib if key == "Pss" else 0.0
    return rss / 1024, pss / 1024


def measure(envs: int, per_process: int, steps: int) -> dict[str, float]:
    """Frames/s of ``steps`` steps of ``envs`` envs, ``per_process`` per process, and the
    workers' memory after them."""
    spec = model_spec("oracle-map")
    overrides = merge_overrides(spec.config_overrides, V3_OVERRIDES)
    config = training_env_config(1, spec.train_sensors, 36, "train", overrides, 500)
    config["episodes_per_scene"] = 5
    odds = [0.02, *[0.98 / 3] * 3]
    vector = make_vector_env(config, envs, envs_per_process=per_process)
    try:
        vector.reset(seed=0)
        rng = np.random.default_rng(0)
        for _ in range(5):  # warm-up
            vector.step(rng.integers(1, 4, envs))
        tick = time.perf_counter()
        for _ in range(steps):
            vector.step(rng.choice(4, size=envs, p=odds))
        fps = steps * envs / (time.perf_counter() - tick)
        workers = _worker_pids(vector)
        rss, pss = _memory_mib(workers)
    finally:
        vector.close()
    return {"fps": fps, "rss_mib": rss, "pss_mib": pss, "processes": len(workers)}


def run_env_processes_bench(
    env_counts: Sequence[int] = (8, 16), per_process: Sequence[int] = (1, 4, 8), steps: int = 100
) -> dict[tuple[int, int], dict[str, float]]:
    """Print and return the figures of each (envs, envs per process)."""
    print(
        f"training envs per process: v3 recipe envs (oracle-map, 36² RGB-D, online train "
        f"episodes), {steps} timed steps after 5, {os.cpu_count()} cores; memory of the worker "
        "processes after the steps"
    )
    print(f"{'envs':>5} {'per proc':>8} {'procs':>5} {'RSS MiB':>8} {'PSS MiB':>8} {'frames/s':>8}")
    results = {}
    for envs in env_counts:
        for k in per_process:
            if k > envs:
                continue
            row = measure(envs, k, steps)
            results[(envs, k)] = row
            print(
                f"{envs:5d} {k:8d} {row['processes']:5.0f} {row['rss_mib']:8.0f} "
                f"{row['pss_mib']:8.0f} {row['fps']:8.1f}"
            )
    return results
