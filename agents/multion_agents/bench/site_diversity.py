"""``multion bench --only diversity``: what drawing goals from goal sites costs in diversity.

The same train houses, the same number of seeded episodes per house, drawn by the online sampler
(:func:`multion.task.sampling.sample_episode`, goals anywhere) and by the goal-site sampler
(:func:`multion.task.goal_sites.sample_site_episode`) for several site counts, and by the online
sampler again from another seed (what the statistics read between two samples of one
distribution). Per sampler:
distinct goal cells per house, the legs' geodesics (start to goal 1, goal to goal) and the room
types each leg joins. Two-sample statistics against the online sampler: Kolmogorov-Smirnov for
the geodesics, a chi-square test of homogeneity for the room-type pairs (with the total
variation distance, which does not grow with the sample).
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Sequence

import numpy as np
from scipy import stats

from multion.config.episode import Episode
from multion.scenes.registry import scene_ids
from multion.sim.geodesic import FieldCache
from multion.sim.navgrid import NavGrid
from multion.sim.simulator import Simulator
from multion.task.goal_sites import GoalSites, house_rooms, room_of, sample_site_episode
from multion.task.sampling import sample_episode

RADIUS = 0.05
"""The default goal radius (``task.goal_radius``): the goals' fields are made with it."""
SEEDS = {"online": 2044, "online-again": 2045}
"""The episodes' seeds; ``online-again``, the online sampler with another seed, gives the
statistics' values between two samples of one distribution (their noise floor)."""
MIN_EXPECTED = 5.0
"""Room-type pairs expected fewer times than this in either sample are pooled into one."""


def _legs(episode: Episode) -> list[tuple[np.ndarray, np.ndarray]]:
    points = [np.asarray(episode.start_position[:2])]
    points += [np.asarray(g.position[:2]) for g in episode.goals]
    return list(zip(points, points[1:], strict=False))


def _room_type_pairs(scene_id: str, episodes: Sequence[Episode]) -> list[str]:
    rooms = house_rooms(scene_id)
    pairs = []
    for episode in episodes:
        for start, end in _legs(episode):
            names = []
            for point in (start, end):
                index = int(room_of(rooms, point[None])[0])
                names.append(rooms[index].room_type if index >= 0 else "doorway")
            pairs.append(" → ".join(names))
    return pairs


def _draw(
    grid: NavGrid, scene: str, sampler: str, count: int, num_goals: int, sites: GoalSites | None
) -> list[Episode]:
    rng = np.random.default_rng(SEEDS.get(sampler, SEEDS["online"]))
    fields = FieldCache()
    episodes: list[Episode] = []
    while len(episodes) < count:
        identity = f"{sampler}-{len(episodes)}"
        if sites is None:
            episode = sample_episode(grid, scene, num_goals, rng, identity, fields=fields)
        else:
            episode = sample_site_episode(sites, grid, scene, num_goals, rng, identity)
        if episode is not None:
            episodes.append(episode)
    return episodes


def run_diversity_bench(
    houses: int = 8,
    episodes_per_house: int = 100,
    num_goals: int = 3,
    site_counts: Sequence[int] = (16, 32, 64),
) -> dict[str, float]:
    """Print and return the diversity figures of each sampler against the online one."""
    samplers = [*SEEDS, *(f"sites-{k}" for k in site_counts)]
    drawn: dict[str, dict[str, list[Episode]]] = {name: {} for name in samplers}
    seconds = dict.fromkeys(samplers, 0.0)
    simulator = Simulator()
    try:
        for scene in scene_ids("train")[:houses]:
            grid = simulator.load_scene(scene)
            for name in samplers:
                sites = None if name in SEEDS else GoalSites(int(name[6:]), RADIUS, 2**40)
                tick = time.perf_counter()
                drawn[name][scene] = _draw(grid, scene, name, episodes_per_house, num_goals, sites)
                seconds[name] += time.perf_counter() - tick
    finally:
        simulator.close()
    print(
        f"{houses} train houses × {episodes_per_house} {num_goals}-ON episodes per sampler "
        f"(seeded); against the online sampler:"
    )
    print(
        f"{'sampler':>12} {'goal cells/house':>17} {'leg median m':>13} {'KS D':>6} "
        f"{'KS p':>8} {'room pairs χ²':>14} {'df':>4} {'χ² p':>8} {'TVD':>5} {'ms/episode':>10}"
    )
    reference_legs, reference_pairs = _pooled(drawn["online"])
    results: dict[str, float] = {}
    for name in samplers:
        legs, pairs = _pooled(drawn[name])
        cells = np.mean(
            [
                len({g.position for e in episodes for g in e.goals})
                for episodes in drawn[name].values()
            ]
        )
        ks = stats.ks_2samp(legs, reference_legs)
        chi2, dof, p_chi2, tvd = room_pair_homogeneity(pairs, reference_pairs)
        ms = 1000 * seconds[name] / (houses * episodes_per_house)
        results.update(
            {
                f"{name}_goal_cells_per_house": float(cells),
                f"{name}_leg_median_m": float(np.median(legs)),
                f"{name}_ks_d": float(ks.statistic),
                f"{name}_ks_p": float(ks.pvalue),
                f"{name}_room_pairs_chi2": chi2,
                f"{name}_room_pairs_p": p_chi2,
                f"{name}_room_pairs_tvd": tvd,
                f"{name}_ms_per_episode": ms,
            }
        )
        print(
            f"{name:>12} {cells:>17.1f} {np.median(legs):>13.2f} {ks.statistic:>6.3f} "
            f"{ks.pvalue:>8.2g} {chi2:>14.1f} {dof:>4d} {p_chi2:>8.2g} {tvd:>5.3f} {ms:>10.1f}"
        )
    return results


def _pooled(by_house: dict[str, list[Episode]]) -> tuple[np.ndarray, list[str]]:
    legs = [d for episodes in by_house.values() for e in episodes for d in e.geodesic_distances]
    pairs = [p for scene, episodes in by_house.items() for p in _room_type_pairs(scene, episodes)]
    return np.asarray(legs), pairs


def room_pair_homogeneity(
    sample: list[str], reference: list[str]
) -> tuple[float, int, float, float]:
    """Chi-square test that two samples of room-type pairs come from one distribution (rare
    pairs pooled), its degrees of freedom and p-value, and their total variation distance."""
    counts, reference_counts = Counter(sample), Counter(reference)
    names = sorted(set(counts) | set(reference_counts))
    table = np.array([[counts[n] for n in names], [reference_counts[n] for n in names]], float)
    tvd = 0.5 * float(np.abs(table[0] / table[0].sum() - table[1] / table[1].sum()).sum())
    expected = table.sum(axis=0) * min(table.sum(axis=1)) / table.sum()
    common = expected >= MIN_EXPECTED
    pooled = np.column_stack([table[:, common], table[:, ~common].sum(axis=1)])
    pooled = pooled[:, pooled.sum(axis=0) > 0]
    chi2, p_value, dof, _ = stats.chi2_contingency(pooled)
    return float(chi2), int(dof), float(p_value), tvd
