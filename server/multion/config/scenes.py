"""Configs of the procedural scenes: the house generator, its floor plans and furniture, and
the train / val / test splits of the houses (their ids: ``multion.scenes.registry``)."""

from __future__ import annotations

from dataclasses import dataclass

from multion.config.ranges import ConfigError

SPLIT_SIZES: dict[str, int] = {"train": 61, "val": 11, "test": 18}

SPLITS: tuple[str, ...] = tuple(SPLIT_SIZES)

GENERATOR_VERSION = 2
"""Version of the procedural scenes: bump it whenever ``house-N`` (or ``room-WxD``) changes, so
datasets made for other houses are refused and navigable grids cached on disk are rebuilt
(``multion.sim.grid_cache``). 1: the small 3–8 room houses;
2: Matterport3D-calibrated houses (issue 12). Here, below the scenes, so that reading a dataset
file (:mod:`multion.config.datasets`) builds no house."""


@dataclass(frozen=True)
class PlanConfig:
    """Knobs of the floor plan (metres unless said otherwise)."""

    min_room_side: float = 2.5
    """Free interior of a room, at least, along both axes."""
    split_fraction: tuple[float, float] = (0.35, 0.65)
    """Where a cell is cut, along its long side."""
    corridor_width: tuple[float, float] = (1.2, 1.6)
    """Free width of a corridor."""
    corridor_probability: float = 0.6
    """Chance that a cell at least ``corridor_min_length`` long is split by a corridor."""
    corridor_min_length: float = 9.0
    max_corridors: int = 2
    corner_cuts: tuple[int, int] = (0, 2)
    """How many corner cells are removed from the rectangle (inclusive range)."""
    min_shared_wall: float = 1.3
    """Two cells are neighbours if they share this much wall (wall centre to wall centre)."""
    door_width: tuple[float, float] = (0.9, 1.1)
    extra_door_probability: float = 0.3
    """Chance that a neighbour pair off the spanning tree gets a door too (a loop)."""
    opening_probability: float = 0.3
    """Chance that a door between two rooms (not corridors) is a wide opening instead."""
    opening_min_wall: float = 2.0
    """Openings only where the shared wall is at least this long."""
    wall_thickness: float = 0.15
    grid: float = 0.05

    def __post_init__(self) -> None:
        if self.door_width[1] > self.min_shared_wall - self.wall_thickness:
            raise ConfigError("door_width must fit in min_shared_wall minus the wall thickness")
        for name in ("corridor_probability", "extra_door_probability", "opening_probability"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if not 0 <= self.corner_cuts[0] <= self.corner_cuts[1] <= 3:
            raise ConfigError(f"corner_cuts must be a range within 0..3, got {self.corner_cuts}")


@dataclass(frozen=True)
class HouseConfig:
    """Knobs of the house generator; the defaults are calibrated to play like Matterport3D's
    buildings (``scripts/calibrate_houses.py``): 8–16 rooms and corridors, about 150–400 m²,
    about half of it navigable."""

    min_rooms: int = 8
    """Rooms including corridors, after corner cuts; valid range 1..max_rooms."""
    max_rooms: int = 16
    """Valid range min_rooms..40."""
    room_area: tuple[float, float] = (11.0, 24.0)
    """m² per room (wall centre to wall centre), drawn per room to size the footprint."""
    footprint_aspect: tuple[float, float] = (1.2, 2.0)
    """Long side / short side of the footprint's rectangle."""
    plan: PlanConfig = PlanConfig()
    wall_height: float = 2.6
    floor_thickness: float = 0.05
    ceiling_thickness: float = 0.05
    door_clear_depth: float = 1.0
    """No furniture this far in front of a door, on both sides."""
    door_clear_margin: float = 0.15
    """… nor this far beside the door opening."""
    furniture_density: float = 1.0
    """Multiplies each furniture item's probability; 0 = empty rooms. Valid range 0..5."""
    clutter: int = 6
    """Rounds of clutter (tables, islands, lamps, boxes, plants … in the middle of rooms) tried
    per room after the furniture along the walls; 0 leaves the middle free. Valid range 0..10."""
    colour_variation: float = 0.04
    """Per-channel shade variation per house."""
    max_attempts: int = 200
    """Floor-plan retries before the footprint is enlarged by 5 %."""

    def __post_init__(self) -> None:
        if not 1 <= self.min_rooms <= self.max_rooms <= 40:
            raise ConfigError(
                f"need 1 <= min_rooms <= max_rooms <= 40, got {self.min_rooms}, {self.max_rooms}"
            )
        if not 0.0 <= self.furniture_density <= 5.0:
            raise ConfigError(f"furniture_density must be in [0, 5], got {self.furniture_density}")
        if not 0 <= self.clutter <= 10:
            raise ConfigError(f"clutter must be in 0..10, got {self.clutter}")

    @property
    def wall_thickness(self) -> float:
        return self.plan.wall_thickness

    @property
    def min_room_side(self) -> float:
        return self.plan.min_room_side


@dataclass(frozen=True)
class PlacementConfig:
    """How carefully furniture is placed."""

    wall_gap: float = 0.02  # gap between furniture and the wall behind it
    item_gap: float = 0.05  # minimum gap between two items
    clearance: float = 0.15  # agent radius (0.1) plus a margin, for the free-area check
    check_radii: tuple[float, ...] = (0.05, 0.075, 0.1, 0.125, 0.15, 0.175)
    cell: float = 0.05  # raster resolution of the connectivity check
    max_depth_fraction: float = 0.6  # an item reaches at most this far across the room
    min_free_fraction: float = 0.35  # this much of the room stays free (at ``clearance``)
    attempts: int = 30  # random placements tried per item before giving up on it
