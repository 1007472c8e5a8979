"""``multion bench --only reset``: online episode sampling, before and after issue 30, in one run.

Two environments on the train houses (36² RGB-D + goal + oracle map, 5 episodes per house as in
the v3 recipe) reset in turn from the same seed, so they draw the same episodes under the same
load. The *before* one checks the agent's steps with :func:`breadth_first_reach` (the
breadth-first search that datasets version 3 came with, kept here as the reference) and computes
every goal's distance field twice, in sampling and again in its reset (no :class:`FieldCache`);
the *after* one is the env as it is. For the after env it also times the fast marchings
(:class:`MarchingClock`), the part of a reset that drawing the same episodes cannot avoid.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
from unittest import mock

import numpy as np

from multion.config.codec import env_config_from_dict
from multion.config.sim import AgentConfig
from multion.sim import geodesic
from multion.sim.geodesic import FieldCache
from multion.sim.navgrid import NavGrid
from multion.task.env import MultiONEnv
from multion.task.step_reach import step_headings

TARGET_MS = {1: 15.0, 3: 40.0}
"""Issue 30's targets for the median reset."""


def breadth_first_reach(
    grid: NavGrid,
    xy: np.ndarray,
    yaw: float,
    goal_fields: Sequence[np.ndarray],
    reach: float,
    agent: AgentConfig = AgentConfig(),
) -> bool:
    """The step-reach check before issue 30 (same contract as
    :func:`multion.task.step_reach.steps_reach_goals`): a breadth-first search, layer by layer,
    until every goal is within ``reach``; positions closer than half a cell are merged."""
    headings = step_headings(yaw, agent)
    moves = agent.forward_step * np.stack([np.cos(headings), np.sin(headings)], axis=-1)
    samples = max(2, int(np.ceil(agent.forward_step / (grid.cell_size / 2))) + 1)
    along = np.linspace(0.0, 1.0, samples)[None, :, None]
    quantum = grid.cell_size / 2
    rows, cols = grid.shape
    seen = np.zeros((2 * rows + 2, 2 * cols + 2), dtype=bool)
    pending = list(range(len(goal_fields)))
    origin = np.asarray(grid.origin)

    def keys(points: np.ndarray) -> np.ndarray:
        index = np.floor((points - origin) / quantum).astype(np.int64) + 1
        index = np.clip(index, 0, np.array(seen.shape[::-1]) - 1)
        return index[..., 1] * seen.shape[1] + index[..., 0]

    frontier = np.asarray(xy, dtype=np.float64)[None, :2]
    seen.flat[keys(frontier)] = True
    while len(frontier):
        pending = [
            g
            for g in pending
            if not (grid.lookup(goal_fields[g], frontier, outside=np.inf) <= reach).any()
        ]
        if not pending:
            return True
        targets = (frontier[:, None, :] + moves[None, :, :]).reshape(-1, 2)
        starts = np.repeat(frontier, len(moves), axis=0)
        fresh = ~seen.flat[keys(targets)]
        targets, starts = targets[fresh], starts[fresh]
        segments = starts[:, None, :] + along * (targets - starts)[:, None, :]
        targets = targets[grid.is_navigable(segments).all(axis=-1)]
        flat, first = np.unique(keys(targets), return_index=True)
        seen.flat[flat] = True
        frontier = targets[first]
    return False


class MarchingClock:
    """Counts and times the fast marchings (:func:`multion.sim.geodesic.distance_field`) made
    while :meth:`watch` is open, wherever they are called from."""

    CALLERS = ("multion.sim.geodesic", "multion.task.dataset", "multion.task.env")

    def __init__(self) -> None:
        self.fields = 0
        self.seconds = 0.0

    @contextmanager
    def watch(self) -> Iterator[None]:
        march = geodesic.distance_field

        def timed(grid: NavGrid, target: np.ndarray, target_radius: float = 0.0) -> np.ndarray:
            tick = time.perf_counter()
            try:
                return march(grid, target, target_radius)
            finally:
                self.seconds += time.perf_counter() - tick
                self.fields += 1

        with ExitStack() as stack:
            for module in self.CALLERS:
                stack.enter_context(mock.patch(f"{module}.distance_field", timed))
            yield


def _env(num_goals: int) -> MultiONEnv:
    config = env_config_from_dict(
        {
            "task": {"num_goals": num_goals},
            "split": "train",
            "sensors": ["rgb", "depth", "goal", "oracle_map"],
            "camera": {"width": 36, "height": 36},
            "maps": {"ego_size": 25},
            "episodes_per_scene": 5,
        }
    )
    return MultiONEnv(config)


def run_reset_bench(resets: int = 60, tasks: Sequence[int] = (1, 3)) -> dict[str, float]:
    """Print and return median and mean reset times, before and after, per task."""
    results: dict[str, float] = {}
    print(
        f"online episode sampling on the train houses: {resets} resets per task, the two envs "
        "in turn (same seed, same episodes)"
    )
    print(f"{'task':>6} {'':>7} {'median ms':>10} {'mean ms':>9} {'p90 ms':>8}")
    for num_goals in tasks:
        before, after = _env(num_goals), _env(num_goals)
        before._field_cache = FieldCache(size=0)  # every field computed where it is used
        times: dict[str, list[float]] = {"before": [], "after": []}
        marching: list[float] = []  # the after env's seconds of fast marching, per reset
        fields: list[int] = []
        same = True
        try:
            for index in range(resets + 1):
                seed = 0 if index == 0 else None
                with mock.patch("multion.task.dataset.steps_reach_goals", breadth_first_reach):
                    tick = time.perf_counter()
                    before.reset(seed=seed)
                    times["before"].append(time.perf_counter() - tick)
                clock = MarchingClock()
                with clock.watch():
                    tick = time.perf_counter()
                    after.reset(seed=seed)
                    times["after"].append(time.perf_counter() - tick)
                marching.append(clock.seconds)
                fields.append(clock.fields)
                same &= before.episode == after.episode
        finally:
            before.close()
            after.close()
        for name, values in times.items():
            ms = 1000 * np.asarray(values[1:])  # the first loads the first house
            results[f"{num_goals}on_{name}_median_ms"] = float(np.median(ms))
            results[f"{num_goals}on_{name}_mean_ms"] = float(ms.mean())
            print(
                f"{num_goals}-ON {name:>7} {np.median(ms):>10.1f} {ms.mean():>9.1f} "
                f"{np.percentile(ms, 90):>8.1f}"
            )
        speedup = (
            results[f"{num_goals}on_before_median_ms"] / results[f"{num_goals}on_after_median_ms"]
        )
        results[f"{num_goals}on_speedup"] = speedup
        results[f"{num_goals}on_same_episodes"] = float(same)
        print(
            f"{'':>6} median speed-up {speedup:.1f}× (target ≥ 20×, median ≤ "
            f"{TARGET_MS[num_goals]:g} ms); same episodes: {'yes' if same else 'NO'}"
        )
        results.update(_marching_share(num_goals, times["after"][1:], marching[1:], fields[1:]))
    return results


def _marching_share(
    num_goals: int, totals: Sequence[float], marching: Sequence[float], fields: Sequence[int]
) -> dict[str, float]:
    """Print and return how much of the after env's resets is fast marching: the part that
    the same episodes cannot do without (one field from the start, one per goal)."""
    total_ms, march_ms = 1000 * np.asarray(totals), 1000 * np.asarray(marching)
    count = np.asarray(fields, dtype=np.float64)
    per_field = float(march_ms.sum() / max(count.sum(), 1.0))
    rest = float(np.median(total_ms - march_ms))
    print(
        f"{'':>6} after: fast marching {np.median(march_ms):.1f} ms of the median reset "
        f"({np.median(count):g} fields, {per_field:.1f} ms each), everything else {rest:.1f} ms"
    )
    return {
        f"{num_goals}on_marching_median_ms": float(np.median(march_ms)),
        f"{num_goals}on_fields_median": float(np.median(count)),
        f"{num_goals}on_ms_per_field": per_field,
        f"{num_goals}on_rest_median_ms": rest,
    }
