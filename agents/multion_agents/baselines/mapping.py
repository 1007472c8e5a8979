"""Building a top-down map from what the camera sees: depth → points, colours → goal objects.

Used by the ``explorer`` baseline, which has no oracle. Everything is in the start frame of
:class:`~multion_agents.baselines.navigation.StartFrameGrid` (x ahead, y left of the start pose),
where GPS and compass place the agent exactly, so no SLAM is needed.

* :class:`DepthProjector` turns a depth image into 3-D points (planar depth, pinhole camera).
* :func:`detect_goals` finds the goal cylinders by colour. Goals are pure red, green, blue, cyan,
  magenta, yellow, black and white; scene colours are muted (saturation ≤ 0.5, value in
  [0.25, 0.78]), so a pixel whose channels are each either ~0 or bright is a goal.
* :class:`SemanticMap` accumulates obstacles, free space and where each goal colour was seen.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, overload

import numpy as np
from scipy import ndimage

from multion.config.sim import CameraConfig
from multion_agents.baselines.navigation import StartFrameGrid
from multion_client.constants import NUM_CATEGORIES

_SENSOR = CameraConfig()
"""The environment's default camera: :class:`CameraModel`'s defaults, read, not copied."""


@dataclass(frozen=True)
class CameraModel:
    """What the agent knows about its camera: the environment's ``camera`` config section
    (:meth:`from_config`), and the depth range it trusts for mapping.

    The sensor's range (``min_depth``, ``max_depth``) decodes a normalised depth value. The
    mapper then clips depth to ``[near_limit, far_limit]``, the range it was tuned with
    (0.5–5 m, the sensor's default range until issue 31): a surface at or beyond ``far`` counts
    as "nothing seen up to there", one at or below ``near`` as "something closer". Beyond 5 m a
    0.1 m map cell is under a pixel's footprint, and the floor is seen at a grazing angle."""

    hfov_deg: float = _SENSOR.hfov_deg
    height: float = _SENSOR.sensor_height
    min_depth: float = _SENSOR.min_depth
    max_depth: float = _SENSOR.max_depth
    normalized: bool = _SENSOR.normalize_depth
    """Depth observations in [0, 1] over ``[min_depth, max_depth]`` (else metres)."""
    near_limit: float = 0.5
    far_limit: float = 5.0

    @classmethod
    def from_config(cls, camera: Mapping[str, Any]) -> CameraModel:
        """From the ``camera`` section of a resolved environment config (nested dicts)."""
        return cls(
            hfov_deg=float(camera["hfov_deg"]),
            height=float(camera["sensor_height"]),
            min_depth=float(camera["min_depth"]),
            max_depth=float(camera["max_depth"]),
            normalized=bool(camera["normalize_depth"]),
        )

    @property
    def near(self) -> float:
        """Depths at or below this (metres) were clipped: the surface is somewhere closer."""
        return max(self.near_limit, self.min_depth)

    @property
    def far(self) -> float:
        """Depths at or above this (metres) were clipped: nothing seen up to there."""
        return min(self.far_limit, self.max_depth)

    def focal(self, width: int) -> float:
        """Focal length in pixels of an image ``width`` pixels wide (square pixels)."""
        return (width / 2) / math.tan(math.radians(self.hfov_deg) / 2)

    # an image in, an image out; one reading in, one number out
    @overload
    def metres(self, depth: np.ndarray) -> np.ndarray: ...
    @overload
    def metres(self, depth: float) -> float: ...
    def metres(self, depth: np.ndarray | float) -> np.ndarray | float:
        """Planar depth in metres, clipped to ``[near, far]``, from depth observation(s)."""
        metres = depth
        if self.normalized:
            metres = self.min_depth + (self.max_depth - self.min_depth) * depth
        return np.clip(metres, self.near, self.far)


# goal colour → category id, by which channels are "on": (red, green, blue)
_PATTERN_TO_CATEGORY = {
    (1, 0, 0): 0,  # red
    (0, 1, 0): 1,  # green
    (0, 0, 1): 2,  # blue
    (0, 1, 1): 3,  # cyan
    (1, 0, 1): 4,  # magenta
    (1, 1, 0): 5,  # yellow
    (0, 0, 0): 6,  # black
    (1, 1, 1): 7,  # white
}
_CODE_TO_CATEGORY = np.full(8, -1, dtype=np.int64)  # r·4 + g·2 + b → category
for (_r, _g, _b), _category in _PATTERN_TO_CATEGORY.items():
    _CODE_TO_CATEGORY[_r * 4 + _g * 2 + _b] = _category

# Houses vary their light (ambient 0.45–0.75, diffuse 0.25–0.5), so a lit goal channel renders
# at 255 × (0.45 … 1.25) ≥ 114. Saturated furniture (a red sofa) has lit channels too, but its
# "off" channels are ≥ 0.08 of full, which renders ≥ 9, while a goal's off channels are exactly 0:
# the threshold on off channels is what tells a goal from a goal-coloured object.
ON_LEVEL = 105
OFF_LEVEL = 3
# a white goal renders its three channels exactly equal (r = g = b); greys rarely do


_EIGHT = np.ones((3, 3), dtype=bool)

Detections = dict[int, tuple[np.ndarray, np.ndarray]]
"""Goal category → (rows, cols) of its pixels."""


def detect_goals(rgb: np.ndarray, min_pixels: int = 3) -> Detections:
    """The pixels of each goal colour in an (H, W, 3) uint8 image (categories with enough)."""
    rows, cols = _candidates(rgb)
    if len(rows) == 0:
        return {}
    pixels = rgb[rows, cols]
    on = pixels >= ON_LEVEL
    valid = (on | (pixels <= OFF_LEVEL)).all(axis=-1)
    code = on[:, 0] * 4 + on[:, 1] * 2 + on[:, 2] * 1
    labels = np.where(valid, _CODE_TO_CATEGORY[code], -1)
    counts = np.bincount(labels + 1, minlength=NUM_CATEGORIES + 1)[1:]
    return {
        int(c): (rows[labels == c], cols[labels == c]) for c in np.flatnonzero(counts >= min_pixels)
    }


def _candidates(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cheap pre-filter: ``(rows, cols)``, in raster order, of the pixels with a channel off (no
    scene colour has one) or bright and balanced (r = g = b ≥ ``ON_LEVEL``).

    Computed on the image's bytes in memory order, where numpy is fast, rather than channel by
    channel (strided) or reduced over the colour axis: byte ``i`` is channel ``i % 3`` of pixel
    ``i // 3``. Candidates are few, so the work on them is small.
    """
    height, width = rgb.shape[:2]
    flat = np.ascontiguousarray(rgb).reshape(-1)
    off = np.flatnonzero(flat <= OFF_LEVEL) // 3
    # a bright byte equal to the next two: at a pixel's first byte, a balanced bright pixel
    same = flat[:-1] == flat[1:]  # byte i equals byte i + 1
    balanced = np.flatnonzero((flat[:-2] >= ON_LEVEL) & same[:-1] & same[1:])
    bright = balanced[balanced % 3 == 0] // 3
    pixels = np.union1d(off, bright) if len(bright) else np.unique(off)
    return pixels // width, pixels % width


def goal_shaped(
    detections: Detections, depth: np.ndarray, camera: CameraModel, max_width: float = 0.2
) -> Detections:
    """The detections whose connected blobs are no wider than ``max_width`` metres.

    Colour alone cannot tell a white goal from white paint under bright light: both render at
    (255, 255, 255). A goal is a 0.1 m cylinder, so a white plant pot or fridge, tens of
    centimetres wide at its depth, is not one.
    """
    focal = camera.focal(depth.shape[1])
    kept: Detections = {}
    for category, (rows, cols) in detections.items():
        # blobs lie inside the box round their pixels: label that box, not the whole image
        r0, c0 = int(rows.min()), int(cols.min())
        mask = np.zeros((int(rows.max()) - r0 + 1, int(cols.max()) - c0 + 1), dtype=bool)
        mask[rows - r0, cols - c0] = True
        labels, count = ndimage.label(mask, structure=_EIGHT)
        blob = labels[rows - r0, cols - c0]
        keep = np.zeros(len(rows), dtype=bool)
        for label in range(1, count + 1):
            inside = blob == label
            z = camera.metres(float(np.median(depth[rows[inside], cols[inside], 0])))
            span = int(cols[inside].max() - cols[inside].min()) + 1
            keep |= inside & (span * z / focal <= max_width)
        if keep.sum() > 0:
            kept[category] = (rows[keep], cols[keep])
    return kept


class DepthProjector:
    """Pixel rays of a square pinhole camera; turns planar depth into start-frame 3-D points."""

    def __init__(self, shape: tuple[int, int], camera: CameraModel, stride: int) -> None:
        height, width = shape
        self.camera = camera
        self.stride = stride
        focal = camera.focal(width)
        rows = np.arange(stride // 2, height, stride)
        cols = np.arange(stride // 2, width, stride)
        self.rows, self.cols = rows, cols
        # per pixel: rightward and upward offsets per metre of depth
        self.right = ((cols + 0.5 - width / 2) / focal)[None, :].repeat(len(rows), axis=0)
        self.column_angles = np.arctan(self.right[0])  # each column's bearing right of ahead
        self.up = ((height / 2 - rows - 0.5) / focal)[:, None].repeat(len(cols), axis=1)

    def points(
        self, depth: np.ndarray, position: np.ndarray, heading: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sampled pixels as ``(xy (h, w, 2), height above floor (h, w), metres (h, w))``.

        ``depth`` is the normalised sensor image (H, W, 1) in [0, 1].
        """
        x, y, height, z = self.project(depth, position, heading)
        return np.stack([x, y], axis=-1), height, z

    def project(
        self, depth: np.ndarray, position: np.ndarray, heading: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`points` as ``(x, y, height, metres)``, each (h, w)."""
        cam = self.camera
        start = self.stride // 2  # the rows and columns of __init__, as a strided view
        sampled = depth[start :: self.stride, start :: self.stride, 0].astype(np.float64)
        z = cam.metres(sampled)
        forward, left = z, -self.right * z
        c, s = math.cos(heading), math.sin(heading)
        x = position[0] + c * forward - s * left
        y = position[1] + s * forward + c * left
        return x, y, cam.height + self.up * z, z


@dataclass(frozen=True)
class MapSettings:
    """Heights that separate floor from obstacles, and how far free space is carved."""

    floor_height: float = 0.06
    obstacle_low: float = 0.08
    obstacle_high: float = 1.55  # the agent is 1.5 m tall
    carve_step: float = 0.05


class SemanticMap:
    """Obstacles, free space and goal sightings in a start-frame grid."""

    def __init__(self, grid: StartFrameGrid, settings: MapSettings = MapSettings()) -> None:
        self.grid = grid
        self.settings = settings
        self.obstacle = np.zeros((grid.size, grid.size), dtype=bool)
        # the obstacles and their 4 neighbours (a binary dilation with a cross), kept as they
        # are added: the explorer's margin round obstacles, without dilating every step
        self.obstacle_grown = np.zeros_like(self.obstacle)
        self.free = np.zeros((grid.size, grid.size), dtype=bool)
        # goal memory: per category, the sum and number of sighted positions (a running mean)
        self._goal_sum = np.zeros((NUM_CATEGORIES, 2))
        self._goal_count = np.zeros(NUM_CATEGORIES, dtype=np.int64)
        self.changed = False
        # cells are only ever added to both layers, so their boxes only grow: kept as cells are
        # set, they spare a scan of the whole map for every plan
        self.obstacle_extent = Extent()
        self.explored_extent = Extent()
        self._free_disc: dict[float, np.ndarray] = {}  # radius → cell offsets in metres

    # ------------------------------------------------------------------ queries
    def goal_position(self, category: int) -> np.ndarray | None:
        """The remembered position of a goal colour, or None if it was never seen."""
        if self._goal_count[category] == 0:
            return None
        mean: np.ndarray = self._goal_sum[category] / self._goal_count[category]
        return mean

    def known_goals(self) -> dict[int, np.ndarray]:
        return {c: self._goal_sum[c] / n for c, n in enumerate(self._goal_count) if n > 0}

    def explored(self) -> np.ndarray:
        return self.free | self.obstacle

    def explored_within(self, box: tuple[int, int, int, int]) -> np.ndarray:
        """:meth:`explored` inside ``box`` = (row0, row1, col0, col1) only."""
        r0, r1, c0, c1 = box
        return self.free[r0:r1, c0:c1] | self.obstacle[r0:r1, c0:c1]

    # ------------------------------------------------------------------ updates
    def mark_free_disc(self, position: np.ndarray, radius: float) -> None:
        """Where the agent stands is free (the camera never sees the floor under its feet)."""
        offsets = self._free_disc.get(radius)
        if offsets is None:
            cells = int(math.ceil(radius / self.grid.cell_size))
            steps = np.arange(-cells, cells + 1) * self.grid.cell_size
            ox, oy = np.meshgrid(steps, steps)
            keep = np.hypot(ox, oy) <= radius
            offsets = self._free_disc[radius] = np.stack([ox[keep], oy[keep]], axis=-1)
        self._add(position[0] + offsets[:, 0], position[1] + offsets[:, 1], self.free)

    def integrate(
        self,
        projector: DepthProjector,
        depth: np.ndarray,
        detections: Detections,
        position: np.ndarray,
        heading: float,
    ) -> list[int]:
        """Add one RGB-D frame; returns the goal categories placed from it."""
        cfg, cam = self.settings, projector.camera
        x, y, height, z = projector.project(depth, position, heading)
        is_goal = np.zeros(z.shape, dtype=bool)
        if detections:
            goal_pixels = np.zeros(depth.shape[:2], dtype=bool)
            for rows, cols in detections.values():
                goal_pixels[rows, cols] = True
            is_goal = goal_pixels[projector.rows][:, projector.cols]
        saturated = z >= cam.far - 1e-3
        # clipped at the near limit: the surface is somewhere closer than 0.5 m, not at 0.5 m;
        # taken at face value it draws a false wall in an arc around the agent (in doorways)
        near = z <= cam.near + 1e-3
        obstacle = (
            (height > cfg.obstacle_low)
            & (height < cfg.obstacle_high)
            & ~is_goal
            & ~saturated
            & ~near
        )
        floor = (height < cfg.floor_height) & ~saturated
        # cells are only ever added: the map changed if some cell set was not set before
        added = self._add(x[obstacle], y[obstacle], self.obstacle)
        added |= self._add(x[floor], y[floor], self.free)
        reach = np.hypot(x - position[0], y - position[1])
        added |= self._carve_free(
            projector, reach, obstacle, near, floor | saturated, position, heading
        )
        self.changed = added
        return self._remember_goals(projector, depth, detections, position, heading)

    def _carve_free(
        self,
        projector: DepthProjector,
        reach: np.ndarray,
        obstacle: np.ndarray,
        near: np.ndarray,
        open_: np.ndarray,
        position: np.ndarray,
        heading: float,
    ) -> bool:
        """Free space along each image column, from the agent to the first obstacle it sees
        (nothing in a column with a surface nearer than the depth range); True if new.
        ``reach``: each sampled pixel's distance from the agent."""
        obstacle_reach = np.where(obstacle, reach, np.inf).min(axis=0)
        obstacle_reach[near.any(axis=0)] = 0.0
        open_reach = np.where(open_, reach, 0.0).max(axis=0)
        limit = np.minimum(obstacle_reach - 0.1, open_reach)  # (columns,)
        step = self.settings.carve_step
        distances = np.arange(step, float(limit.max(initial=0.0)), step)
        if len(distances) == 0:
            return False
        bearings = heading - projector.column_angles  # left of the heading is positive
        # only the points short of each column's limit (the same numbers as computing all)
        along, column = np.nonzero(distances[:, None] < limit[None, :])
        ahead = distances[along]
        x = position[0] + ahead * np.cos(bearings)[column]
        y = position[1] + ahead * np.sin(bearings)[column]
        return self._add(x, y, self.free)

    def _remember_goals(
        self,
        projector: DepthProjector,
        depth: np.ndarray,
        detections: Detections,
        position: np.ndarray,
        heading: float,
    ) -> list[int]:
        cam = projector.camera
        width = depth.shape[1]
        focal = cam.focal(width)
        c, s = math.cos(heading), math.sin(heading)
        placed = []
        for category, (rows, cols) in detections.items():
            z = cam.metres(depth[rows, cols, 0])
            reliable = z < cam.far - 1e-3
            if reliable.sum() < 3:
                continue  # too far to place; it will be seen again from closer
            z, cols = z[reliable], cols[reliable]
            forward = float(np.median(z))
            left = float(np.median(-(cols + 0.5 - width / 2) / focal * z))
            point = np.array(
                [position[0] + c * forward - s * left, position[1] + s * forward + c * left]
            )
            self._goal_sum[category] += point
            self._goal_count[category] += 1
            placed.append(category)
        return placed

    def _add(self, x: np.ndarray, y: np.ndarray, layer: np.ndarray) -> bool:
        """Set the cells of the points ``(x, y)`` (those on the map) in ``layer``, ``free`` or
        ``obstacle``; True if one was not set yet. Only new cells grow the boxes and margin."""
        grid, size = self.grid, self.grid.size
        # the cells of StartFrameGrid.to_cell, on flat indices
        rows = np.rint(grid.half - x / grid.cell_size).astype(np.int64)
        cols = np.rint(grid.half - y / grid.cell_size).astype(np.int64)
        # as unsigned, a negative index is huge: one comparison checks both ends
        ok = (rows.view(np.uint64) < size) & (cols.view(np.uint64) < size)
        cells = (rows * size + cols)[ok]
        flat = layer.reshape(-1)  # a view: layers are contiguous
        cells = cells[~flat[cells]]
        if len(cells) == 0:
            return False
        flat[cells] = True
        rows, cols = np.divmod(cells, size)
        self.explored_extent.add(rows, cols)
        if layer is self.obstacle:
            self.obstacle_extent.add(rows, cols)
            self._grow(rows, cols)
        return True

    def _grow(self, rows: np.ndarray, cols: np.ndarray) -> None:
        size = self.grid.size
        for dr, dc in ((0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)):
            r, c = rows + dr, cols + dc
            ok = (r >= 0) & (r < size) & (c >= 0) & (c < size)
            self.obstacle_grown[r[ok], c[ok]] = True


@dataclass
class Extent:
    """The smallest box round the cells added so far (cells are never removed)."""

    row0: int = 0
    row1: int = -1  # inclusive; row1 < row0: no cell yet
    col0: int = 0
    col1: int = -1

    @property
    def empty(self) -> bool:
        return self.row1 < self.row0

    def add(self, rows: np.ndarray, cols: np.ndarray) -> None:
        r0, r1, c0, c1 = int(rows.min()), int(rows.max()), int(cols.min()), int(cols.max())
        if self.empty:
            self.row0, self.row1, self.col0, self.col1 = r0, r1, c0, c1
            return
        self.row0, self.row1 = min(self.row0, r0), max(self.row1, r1)
        self.col0, self.col1 = min(self.col0, c0), max(self.col1, c1)

    def bounds(self) -> tuple[int, int, int, int]:
        """(row0, row1, col0, col1) with exclusive ends; row0 ≥ row1 when empty."""
        return self.row0, self.row1 + 1, self.col0, self.col1 + 1

    def box(self, margin: int, size: int) -> tuple[int, int, int, int]:
        """As :func:`~.navigation.bounding_box` gives it (the whole map when empty)."""
        if self.empty:
            return 0, size, 0, size
        return (
            max(0, self.row0 - margin),
            min(size, self.row1 + margin + 1),
            max(0, self.col0 - margin),
            min(size, self.col1 + margin + 1),
        )
