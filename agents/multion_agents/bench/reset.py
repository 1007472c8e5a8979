"""``multion bench --only reset``: the two train samplers' resets side by side (issue 44).

Two environments on the train houses (36² RGB-D + goal + oracle map, 5 episodes per house as in
the v3 recipe) reset in turn from the same seed, under the same load: one draws episodes as
every run before issue 44 did (``train_sampler = "online"``, ``m + 1`` fields marched per
episode), the other from the houses' goal sites (``"sites"``, :mod:`multion.task.goal_sites`).
The sites env first marches every site of every train house (what a training run's env has done
after its first visits; the time is printed), so its resets are timed as they are once warm.
For both it times the fast marchings (:class:`MarchingClock`) within each reset.

Those medians leave out what a training run also pays: house switches and the first marchings of
each site. :func:`time_plain_resets`, run first (before any site is marched in the process), times
a plain ``MultiONEnv`` on the train split at the default config (36² RGB-D + goal, 25 episodes
per house): resets that stay in one house and resets that switch houses, apart, and the mean of
all. Houses load from the navigable-grid cache on disk where it holds them (a first-ever load
builds the grid: seconds).

:func:`breadth_first_reach` is the step-reach check before issue 30, kept as the reference that
``tests/task/test_step_reach.py`` compares the best-first search with.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
from unittest import mock

import numpy as np

from multion.config.codec import env_config_from_dict
from multion.config.sim import AgentConfig
from multion.config.task import EnvConfig
from multion.scenes.registry import scene_ids
from multion.sim import geodesic
from multion.sim.navgrid import NavGrid
from multion.task.env import MultiONEnv
from multion.task.goal_sites import GoalSites
from multion.task.step_reach import step_headings

TARGET_MS = {1: 15.0, 3: 40.0}
"""Issue 30's and 44's targets for the median reset."""


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
        flat: np.ndarray = index[..., 1] * seen.shape[1] + index[..., 0]
        return flat

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

    CALLERS = (
        "multion.sim.geodesic",
        "multion.task.sampling",
        "multion.task.env",
        "multion.task.goal_sites",
    )

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


def bench_config(num_goals: int, sampler: str) -> EnvConfig:
    """The bench's train env: 36² RGB-D + goal + oracle map, 5 episodes per house (v3)."""
    return env_config_from_dict(
        {
            "task": {"num_goals": num_goals, "train_sampler": sampler},
            "split": "train",
            "sensors": ["rgb", "depth", "goal", "oracle_map"],
            "camera": {"width": 36, "height": 36},
            "maps": {"ego_size": 25},
            "episodes_per_scene": 5,
        }
    )


def _env(num_goals: int, sampler: str) -> MultiONEnv:
    return MultiONEnv(bench_config(num_goals, sampler))


def plain_config(num_goals: int) -> EnvConfig:
    """A plain train env at the default config but for a 36² camera: RGB-D + goal."""
    return env_config_from_dict(
        {
            "task": {"num_goals": num_goals},
            "split": "train",
            "sensors": ["rgb", "depth", "goal"],
            "camera": {"width": 36, "height": 36},
        }
    )


def time_plain_resets(num_goals: int, resets: int = 150) -> dict[str, float]:
    """Time ``resets`` resets of a plain train env after its first (which loads the first
    house): the median of those that stay in one house and of those that switch houses, and the
    mean of all; printed and returned (ms)."""
    env = MultiONEnv(plain_config(num_goals))
    try:
        env.reset(seed=0)
        same: list[float] = []
        switch: list[float] = []
        for _ in range(resets):
            scene = env.episode.scene_id if env.episode is not None else None
            tick = time.perf_counter()
            env.reset()
            ms = 1000 * (time.perf_counter() - tick)
            assert env.episode is not None
            (same if env.episode.scene_id == scene else switch).append(ms)
    finally:
        env.close()
    every = np.asarray(same + switch)
    results = {
        f"{num_goals}on_plain_same_house_median_ms": float(np.median(same)),
        f"{num_goals}on_plain_switch_median_ms": float(np.median(switch)) if switch else 0.0,
        f"{num_goals}on_plain_mean_ms": float(every.mean()),
        f"{num_goals}on_plain_switches": float(len(switch)),
    }
    switched = f"median {np.median(switch):.0f} ms" if switch else "none"
    print(
        f"{num_goals}-ON   plain {np.median(same):>10.1f} {every.mean():>9.1f} "
        f"{np.percentile(every, 90):>8.1f}  median in one house; {len(switch)} house switches: "
        f"{switched}"
    )
    return results


def march_every_site(sites: GoalSites, env: MultiONEnv) -> float:
    """March every goal site of every train house into ``sites``'s cache (the process's, which
    ``env`` reads too, warmed as its visits would); seconds taken."""
    tick = time.perf_counter()
    for scene in scene_ids("train"):
        house = sites.house(scene, env.sim.load_scene(scene))
        for site in range(len(house.sites)):
            sites.values(house, site)
    return time.perf_counter() - tick


def run_reset_bench(
    resets: int = 60, tasks: Sequence[int] = (1, 3), warm: bool = True, plain: int = 150
) -> dict[str, float]:
    """Print and return, per task, ``plain`` resets of a plain train env (:func:`time_plain_resets`),
    then the median and mean resets of both samplers. ``warm``: march every site first (several
    minutes on a cold grid cache); without it the sites env's resets include its first
    marchings."""
    results: dict[str, float] = {}
    print(
        f"a plain train env (default config, 36² RGB-D + goal, sites cold, 25 episodes per "
        f"house): {plain} resets per task after the first"
    )
    print(f"{'task':>6} {'sampler':>7} {'median ms':>10} {'mean ms':>9} {'p90 ms':>8}")
    for num_goals in tasks:
        results.update(time_plain_resets(num_goals, plain))
    print(
        f"train episodes: {resets} resets per task, the online and the sites env in turn "
        "(same seed; sites warm: every site marched first; medians leave house switches out)"
    )
    task = bench_config(1, "sites").task
    # a view of the process's site cache held through both tasks: the cache is dropped when
    # its last user closes, and a site's field ignores m, so the 3-ON env reads the 1-ON's
    keeper = GoalSites(task.goal_sites, task.goal_radius, task.goal_site_cache_mib * 2**20)
    try:
        for num_goals in tasks:
            envs = {"online": _env(num_goals, "online"), "sites": _env(num_goals, "sites")}
            try:
                if warm and "warm_up_s" not in results:
                    seconds = march_every_site(keeper, envs["sites"])
                    results["warm_up_s"] = seconds
                    results["sites_fields_held"] = float(keeper.fields_held)
                    results["sites_held_mib"] = keeper.held_bytes / 2**20
                    print(
                        f"sites: marched all {keeper.fields_held} site fields of the train "
                        f"houses in {seconds:.0f} s, {keeper.held_bytes / 2**20:.0f} MiB held "
                        "(one cache per process)"
                    )
                results.update(_time_resets(num_goals, envs, resets))
            finally:
                for env in envs.values():
                    env.close()
    finally:
        keeper.close()
    return results


def _time_resets(num_goals: int, envs: dict[str, MultiONEnv], resets: int) -> dict[str, float]:
    times: dict[str, list[float]] = {name: [] for name in envs}
    marching: dict[str, list[float]] = {name: [] for name in envs}
    fields: dict[str, list[int]] = {name: [] for name in envs}
    for index in range(resets + 1):
        for name, env in envs.items():
            clock = MarchingClock()
            with clock.watch():
                tick = time.perf_counter()
                env.reset(seed=0 if index == 0 else None)
                times[name].append(time.perf_counter() - tick)
            marching[name].append(clock.seconds)
            fields[name].append(clock.fields)
    results: dict[str, float] = {}
    print(
        f"{'task':>6} {'sampler':>7} {'median ms':>10} {'mean ms':>9} {'p90 ms':>8}  "
        "fast marching (median ms, fields)"
    )
    for name in envs:
        ms = 1000 * np.asarray(times[name][1:])  # the first loads the first house
        march_ms = 1000 * np.asarray(marching[name][1:])
        count = np.asarray(fields[name][1:], dtype=np.float64)
        key = f"{num_goals}on_{name}"
        results[f"{key}_median_ms"] = float(np.median(ms))
        results[f"{key}_mean_ms"] = float(ms.mean())
        results[f"{key}_marching_median_ms"] = float(np.median(march_ms))
        results[f"{key}_fields_median"] = float(np.median(count))
        results[f"{key}_fields_mean"] = float(count.mean())
        results[f"{key}_rest_median_ms"] = float(np.median(ms - march_ms))
        print(
            f"{num_goals}-ON {name:>7} {np.median(ms):>10.1f} {ms.mean():>9.1f} "
            f"{np.percentile(ms, 90):>8.1f}  {np.median(march_ms):.1f} ms, "
            f"{np.median(count):g} fields (mean {count.mean():.2f}); everything else "
            f"{np.median(ms - march_ms):.1f} ms"
        )
    speedup = results[f"{num_goals}on_online_median_ms"] / results[f"{num_goals}on_sites_median_ms"]
    results[f"{num_goals}on_speedup"] = speedup
    print(
        f"{'':>6} sites: median {speedup:.1f}× faster (target: median ≤ "
        f"{TARGET_MS[num_goals]:g} ms)"
    )
    return results
