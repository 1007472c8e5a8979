"""``multion bench --only cache``: house builds with a cold and a warm navigable-grid cache, and
an oracle-planner evaluation without the cache and with a warm one."""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np

from multion.sim import grid_cache, simulator
from multion_agents.evaluate import EvalSettings, evaluate

CACHE_SCENES = ("house-00061", "house-00066")


def bench_cache(eval_episodes: int = 100) -> dict[str, float]:
    """House builds (world + navigable grid) with a cold and a warm disk cache, and the wall
    time of an oracle-planner evaluation without the cache and with a warm one (a private
    temporary cache directory: the user's cache is not touched)."""
    results: dict[str, float] = {}
    saved = os.environ.get(grid_cache.CACHE_ENV)
    with tempfile.TemporaryDirectory(prefix="multion-bench-navgrids-") as directory:
        os.environ[grid_cache.CACHE_ENV] = directory
        try:
            cold = [_build_seconds(scene) for scene in CACHE_SCENES]
            warm = [_build_seconds(scene) for scene in CACHE_SCENES]
            results["build_cold_s"] = float(np.mean(cold))
            results["build_warm_s"] = float(np.mean(warm))
            ratio = results["build_cold_s"] / results["build_warm_s"]
            results["build_speedup"] = ratio
            print(
                f"house build (world + navigable grid), mean of {', '.join(CACHE_SCENES)}: "
                f"cold {results['build_cold_s']:.2f} s, cached {results['build_warm_s']:.3f} s: "
                f"{ratio:.1f}× faster   (target ≥ 10×)"
            )
            if eval_episodes > 0:
                os.environ[grid_cache.CACHE_ENV] = "off"
                before = _eval_seconds(eval_episodes)
                os.environ[grid_cache.CACHE_ENV] = directory
                _eval_seconds(eval_episodes)  # fills the cache with every val house
                after = _eval_seconds(eval_episodes)
                results["eval_no_cache_s"], results["eval_warm_cache_s"] = before, after
                print(
                    f"{eval_episodes}-episode 3-ON val oracle-planner evaluation (local server, "
                    f"1 worker): no grid cache {before:.1f} s, warm cache {after:.1f} s: "
                    f"{before / after:.1f}× faster"
                )
        finally:
            if saved is None:
                os.environ.pop(grid_cache.CACHE_ENV, None)
            else:
                os.environ[grid_cache.CACHE_ENV] = saved
    return results


def _build_seconds(scene: str) -> float:
    """Seconds to load ``scene`` in a fresh simulator, as a new worker process would (the
    in-process grid cache emptied first; the disk cache as it is)."""
    simulator._GRID_CACHE.clear()
    start = time.perf_counter()
    sim = simulator.Simulator()
    sim.load_scene(scene)
    seconds = time.perf_counter() - start
    sim.close()
    return seconds


def _eval_seconds(episodes: int) -> float:
    """Wall time of ``multion eval --agent oracle-planner --task 3-on --split val``."""
    settings = EvalSettings(agent="oracle-planner", num_goals=3, split="val", episodes=episodes)
    start = time.perf_counter()
    evaluate(settings, progress=False)
    return time.perf_counter() - start
