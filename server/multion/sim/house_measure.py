"""What a procedural house measures: rooms, corridors, doors, footprint, navigable area and
build time (what the houses were calibrated on; ``scripts/calibrate_houses.py --houses`` and
``multion leaderboard check --generate`` print them)."""

from __future__ import annotations

import time
from dataclasses import dataclass

from multion.scenes.registry import layout_for
from multion.sim.simulator import Simulator


@dataclass(frozen=True)
class HouseMeasure:
    rooms: int
    """Rooms, corridors included."""
    corridors: int
    doors: int
    footprint_m2: float
    navigable_m2: float
    build_s: float
    """Layout and navigable grid (from the grid cache when it has them)."""

    @property
    def navigable_share(self) -> float:
        return self.navigable_m2 / self.footprint_m2


def measure_house(simulator: Simulator, scene: str) -> HouseMeasure:
    """Build ``scene`` in ``simulator`` and measure it."""
    tick = time.perf_counter()
    meta = layout_for(scene).metadata
    grid = simulator.load_scene(scene)
    took = time.perf_counter() - tick
    return HouseMeasure(
        rooms=int(meta["room_count"]),
        corridors=int(meta["corridor_count"]),
        doors=int(meta["door_count"]),
        footprint_m2=float(meta["footprint_area"]),
        navigable_m2=float(grid.navigable.sum()) * grid.cell_size**2,
        build_s=took,
    )
