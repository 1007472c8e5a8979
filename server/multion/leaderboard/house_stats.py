"""How hidden houses compare with the packaged val houses: the same benchmark, or an easier one?

``multion leaderboard check --generate`` prints one row per (track, phase) beside val's: rooms,
footprint and navigable share, the numbers the houses were calibrated on (issue 12).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from multion.scenes.registry import layout_for, scene_ids
from multion.sim.house_check import geometry_problems, grid_problems
from multion.sim.house_measure import measure_house
from multion.sim.simulator import Simulator


@dataclass(frozen=True)
class HouseStats:
    """Summary of a set of procedural houses."""

    houses: int
    rooms: tuple[int, int, float]
    """min, max, mean room count (corridors included)."""
    footprint_m2: tuple[float, float, float]
    """min, max, mean footprint area."""
    navigable: float
    """Mean navigable share of the footprint."""
    problems: tuple[str, ...] = ()
    """Unsound houses (:mod:`multion.sim.house_check`): "house: what is wrong"."""

    def row(self, name: str, name_width: int = 28) -> str:
        r, f = self.rooms, self.footprint_m2
        rooms = span(str(r[0]), str(r[1]))
        low_high = span(f"{f[0]:.0f}", f"{f[1]:.0f}")
        footprint = f"{f[2]:.0f}" if low_high == f"{f[2]:.0f}" else f"{f[2]:.0f} ({low_high})"
        return (
            f"{name:<{name_width}}{self.houses:>7}{rooms:>10}{r[2]:>6.1f}{footprint:>20}"
            f"{100 * self.navigable:>9.1f}"
        )


def span(low: str, high: str) -> str:
    """``8–16``, or ``1`` where both ends are one (never ``1–1``)."""
    return low if low == high else f"{low}–{high}"


def header(name_width: int = 28) -> str:
    """The column titles over :meth:`HouseStats.row`'s columns."""
    return (
        f"{'houses of':<{name_width}}{'count':>7}{'rooms':>10}{'mean':>6}"
        f"{'m² mean (range)':>20}{'nav %':>9}"
    )


def stats_table(rows: Sequence[tuple[str, HouseStats]]) -> list[str]:
    """The header and one line per (name, stats), the name column as wide as the longest name
    (a long track or phase name must not push its numbers out of their columns)."""
    width = max([28, *(len(name) + 2 for name, _ in rows)])
    return [header(width), *(stats.row(name, width) for name, stats in rows)]


def house_stats(houses: Sequence[str]) -> HouseStats:
    """Rooms, footprint and navigable share of ``houses`` (builds them: seconds each)."""
    simulator = Simulator()
    problems: list[str] = []
    try:
        measures = []
        for house in houses:
            measures.append(measure_house(simulator, house))
            layout, grid = layout_for(house), simulator.load_scene(house)
            agent = simulator.agent_config
            found = geometry_problems(layout) + grid_problems(
                layout, grid, agent.radius, agent.height
            )
            problems += [f"{house}: {p}" for p in found]
    finally:
        simulator.close()
    rooms = [h.rooms for h in measures]
    areas = [h.footprint_m2 for h in measures]
    return HouseStats(
        len(houses),
        (min(rooms), max(rooms), float(np.mean(rooms))),
        (min(areas), max(areas), float(np.mean(areas))),
        float(np.mean([h.navigable_share for h in measures])),
        tuple(problems),
    )


def val_stats() -> HouseStats:
    """The packaged val houses' (the calibrated benchmark)."""
    return house_stats(scene_ids("val"))
