"""Top-down pictures of scenes (and, later, episodes) with Pillow.

A picture covers exactly the navigable grid it is given: grid cell ``(i, j)`` is the square whose
centre is ``x = origin[0] + (j + 0.5) * cell_size``, ``y = origin[1] + (i + 0.5) * cell_size``.
The picture is flipped so that +y points up, like a floor plan. :class:`PictureFrame` and
:func:`world_to_pixel` convert world metres to pixels, so other drawings (agent paths, goals) can
be added on top of :func:`scene_picture`'s result with the same numbers.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from multion.config.episode import Episode
from multion.scenes.layout import SceneLayout

NAVIGABLE = (236, 232, 222)
BLOCKED = (120, 118, 114)
OUTSIDE = (250, 250, 248)
"""Where no floor is (cut corners, the margin): the page's white rather than a grey block, so a
picture of an L-shaped house does not look half empty."""
WALL = (48, 48, 52)
FURNITURE_EDGE = (150, 95, 60)
DOOR = (70, 140, 200)
TEXT = (20, 20, 20)
ROOM_LABEL = (70, 70, 70)
LABEL_PATCH = (250, 249, 245)
LABEL_MARGIN = 3.0
"""Pixels between a room label's patch and its room's edge (the wall, any doorway)."""


@dataclass(frozen=True)
class PictureFrame:
    """Which part of the world a picture shows and at what scale."""

    origin: tuple[float, float]  # world (x, y) of the picture's lower-left corner
    size: tuple[float, float]  # width and height covered, metres
    pixels_per_metre: float

    @property
    def image_size(self) -> tuple[int, int]:
        """Picture ``(width, height)`` in pixels."""
        return (
            max(1, round(self.size[0] * self.pixels_per_metre)),
            max(1, round(self.size[1] * self.pixels_per_metre)),
        )


def picture_frame(
    navigable: np.ndarray,
    origin: tuple[float, float],
    cell_size: float,
    pixels_per_metre: float = 40,
) -> PictureFrame:
    """The frame :func:`scene_picture` uses for a grid of this shape, origin and cell size."""
    rows, cols = navigable.shape
    return PictureFrame(
        (float(origin[0]), float(origin[1])), (cols * cell_size, rows * cell_size), pixels_per_metre
    )


def world_to_pixel(x: float, y: float, frame: PictureFrame) -> tuple[float, float]:
    """Pixel coordinates ``(column, row)`` of world point ``(x, y)``; rows grow downwards."""
    ppm = frame.pixels_per_metre
    top = frame.origin[1] + frame.size[1]
    return ((x - frame.origin[0]) * ppm, (top - y) * ppm)


def _rect_pixels(x0: float, y0: float, x1: float, y1: float, frame: PictureFrame) -> list[float]:
    (px0, py1), (px1, py0) = world_to_pixel(x0, y0, frame), world_to_pixel(x1, y1, frame)
    return [px0, py0, px1, py1]


def draw_layout(
    draw: ImageDraw.ImageDraw,
    layout: SceneLayout,
    frame: PictureFrame,
    keep_clear: Sequence[Sequence[float]] = (),
) -> None:
    """Draw walls (filled), furniture (outlined), room types and doors of ``layout`` onto ``draw``;
    room labels avoid the pixel boxes ``keep_clear`` (markers drawn on top later)."""
    furniture = [b for b in layout.boxes if b.kind == "furniture"]
    # Large boxes first so small parts (legs, handles) stay visible on top.
    furniture.sort(key=lambda b: -b.half_extents[0] * b.half_extents[1])
    for box in furniture:
        (x0, y0, _), (x1, y1, _) = box.min_corner, box.max_corner
        fill = tuple(int(255 * c) for c in box.rgba[:3])
        draw.rectangle(_rect_pixels(x0, y0, x1, y1, frame), fill=fill, outline=FURNITURE_EDGE)
    for box in layout.boxes:
        if box.kind == "wall":
            (x0, y0, _), (x1, y1, _) = box.min_corner, box.max_corner
            draw.rectangle(_rect_pixels(x0, y0, x1, y1, frame), fill=WALL)
    for label in fitted_room_labels(draw, layout, frame, label_font(frame), keep_clear):
        left, top, _, _ = draw.textbbox((0, 0), label.text, font=label.font)
        patch, pad = label.box, LABEL_PAD
        draw.rectangle(patch, fill=LABEL_PATCH)
        at = (patch[0] + pad - left, patch[1] + pad - top)
        draw.text(at, label.text, fill=ROOM_LABEL, font=label.font, align="center")
    for door in layout.doors:
        cx, cy = door.center
        dx, dy = (door.width / 2, 0.0) if door.axis == "x" else (0.0, door.width / 2)
        a, b = world_to_pixel(cx - dx, cy - dy, frame), world_to_pixel(cx + dx, cy + dy, frame)
        draw.line([a, b], fill=DOOR, width=max(1, round(frame.pixels_per_metre * 0.04)))


def _under_floor(
    layout: SceneLayout, shape: tuple[int, ...], origin: tuple[float, float], cell_size: float
) -> np.ndarray:
    """Grid cells whose centre lies on one of the layout's floor slabs."""
    xs = origin[0] + (np.arange(shape[1]) + 0.5) * cell_size
    ys = origin[1] + (np.arange(shape[0]) + 0.5) * cell_size
    under = np.zeros(shape[:2], dtype=bool)
    for box in layout.boxes:
        if box.kind == "floor":
            (x0, y0, _), (x1, y1, _) = box.min_corner, box.max_corner
            under |= ((ys >= y0) & (ys <= y1))[:, None] & ((xs >= x0) & (xs <= x1))[None, :]
    return under


def furniture_pixels(layout: SceneLayout, frame: PictureFrame) -> list[list[float]]:
    """The pixel boxes of the layout's furniture."""
    return [
        _rect_pixels(b.min_corner[0], b.min_corner[1], b.max_corner[0], b.max_corner[1], frame)
        for b in layout.boxes
        if b.kind == "furniture"
    ]


MIN_LABEL_SIZE = 8
"""The smallest room label text, pixels: a room too small for its type at this size (a short
hallway on a small video map) is labelled by a short form, or not at all, rather than
by text that spills over walls, doorways and paths or out of the picture."""
LABEL_PAD = 2
"""Pixels between a label's text and the edge of its patch."""


@dataclass(frozen=True)
class RoomLabel:
    """A room label as drawn: its text (a line per word where wrapped), the pixel box of its
    patch and the font it is written in."""

    text: str
    box: list[float]
    font: ImageFont.FreeTypeFont | ImageFont.ImageFont


@functools.lru_cache(maxsize=32)
def _font(size: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    return ImageFont.load_default(size=size)


SHORT_ROOM_NAMES = {"bedroom": "bed", "bathroom": "bath", "hallway": "hall", "kitchen": "kit."}
"""Short forms of one-word room types, for rooms too small for the whole word."""


def _label_texts(room_type: str) -> list[str]:
    """What a room's label may say, best first: the whole type, a line per word, the first
    word (or a short form)."""
    words = room_type.replace("_", " ").split()
    texts = [" ".join(words)]
    if len(words) > 1:
        texts += ["\n".join(words), words[0]]
    elif words and words[0] in SHORT_ROOM_NAMES:
        texts.append(SHORT_ROOM_NAMES[words[0]])
    return texts


def _fitting_label(
    draw: ImageDraw.ImageDraw, room_type: str, space: tuple[float, float], size: int
) -> tuple[str, Any, tuple[float, float]] | None:
    """The first text and font (largest first, down to :data:`MIN_LABEL_SIZE`) whose patch fits
    in ``space`` pixels; the whole type at any size before the shortened one."""
    for text in _label_texts(room_type):
        for points in range(size, MIN_LABEL_SIZE - 1, -1):
            font = _font(points)
            left, top, right, bottom = draw.textbbox((0, 0), text, font=font)
            patch = (right - left + 2 * LABEL_PAD, bottom - top + 2 * LABEL_PAD)
            if patch[0] <= space[0] and patch[1] <= space[1]:
                return text, font, patch
    return None


def fitted_room_labels(
    draw: ImageDraw.ImageDraw,
    layout: SceneLayout,
    frame: PictureFrame,
    font: Any,
    keep_clear: Sequence[Sequence[float]] = (),
) -> list[RoomLabel]:
    """Each room's label, inside its room and the picture: in ``font`` where it fits, else
    wrapped, smaller or shortened (:func:`_fitting_label`); rooms too small for any are left
    unlabelled. Placed by :func:`place_label`: where it covers the least furniture, clear of the
    labels placed before it and of the boxes ``keep_clear`` (goal markers)."""
    obstacles = furniture_pixels(layout, frame)
    width, height = frame.image_size
    size = round(font.size) if isinstance(font, ImageFont.FreeTypeFont) else MIN_LABEL_SIZE
    labels: list[RoomLabel] = []
    for room in layout.rooms:
        x0, y0, x1, y1 = _rect_pixels(*room.rect, frame)
        inside = [max(0.0, x0), max(0.0, y0), min(float(width), x1), min(float(height), y1)]
        space = (inside[2] - inside[0] - 2 * LABEL_MARGIN, inside[3] - inside[1] - 2 * LABEL_MARGIN)
        fitted = _fitting_label(draw, room.room_type, space, size)
        if fitted is None:
            continue
        text, chosen, patch = fitted
        avoid = [*keep_clear, *(label.box for label in labels)]
        labels.append(RoomLabel(text, place_label(inside, patch, obstacles, avoid), chosen))
    return labels


def room_labels(
    draw: ImageDraw.ImageDraw,
    layout: SceneLayout,
    frame: PictureFrame,
    font: Any,
    keep_clear: Sequence[Sequence[float]] = (),
) -> list[tuple[str, list[float]]]:
    """The text and pixel box of each room label (:func:`fitted_room_labels`)."""
    return [
        (label.text, label.box)
        for label in fitted_room_labels(draw, layout, frame, font, keep_clear)
    ]


def label_font(frame: PictureFrame) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """Text scales with the picture (0.3 m high), so pictures at one scale share a text size."""
    return _font(max(11, round(0.3 * frame.pixels_per_metre)))


def _overlap(a: Sequence[float], b: Sequence[float]) -> float:
    width = min(a[2], b[2]) - max(a[0], b[0])
    height = min(a[3], b[3]) - max(a[1], b[1])
    return max(0.0, width) * max(0.0, height)


def place_label(
    room: Sequence[float],
    size: tuple[float, float],
    obstacles: Sequence[Sequence[float]],
    placed: Sequence[Sequence[float]],
    steps: int = 8,
) -> list[float]:
    """Where a label of ``size`` pixels goes in a ``room`` (pixel box): the spot of a grid of
    candidates inside it that covers the least furniture, never another label if avoidable;
    top-left first on equal cover (the usual place on a floor plan)."""
    x0, y0 = room[0] + LABEL_MARGIN, room[1] + LABEL_MARGIN
    free_x = max(0.0, room[2] - LABEL_MARGIN - size[0] - x0)
    free_y = max(0.0, room[3] - LABEL_MARGIN - size[1] - y0)
    best: tuple[float, list[float]] | None = None
    for j in range(steps + 1):
        for i in range(steps + 1):
            box = [x0 + free_x * i / steps, y0 + free_y * j / steps]
            box += [box[0] + size[0], box[1] + size[1]]
            cost = sum(_overlap(box, o) for o in obstacles)
            cost += 1e6 * sum(_overlap(box, p) for p in placed)
            if best is None or cost < best[0]:
                best = (cost, box)
            if cost == 0:
                return box
    assert best is not None
    return best[1]


FOOTER_MARGIN = 8
"""Pixels around the footer's scale bar and id."""


def _with_footer(
    plan: Image.Image, frame: PictureFrame, caption: str | None, font: Any
) -> Image.Image:
    """``plan`` over a white footer holding a 1 m scale bar and, if given, ``caption`` (the
    scene id): beside the bar if there is room, else under it, and the picture widened rather
    than the id cut. The plan keeps its pixels and its place (top left), so
    :func:`world_to_pixel` still applies to the result."""
    probe = ImageDraw.Draw(plan)
    ppm, m = frame.pixels_per_metre, FOOTER_MARGIN
    left, top, right, bottom = (int(v) for v in probe.textbbox((0, 0), "1 m", font=font))
    line = bottom - top
    bar_width = round(ppm) + 5 + (right - left)
    text_width = 0
    if caption:
        c_left, _, c_right, _ = (int(v) for v in probe.textbbox((0, 0), caption, font=font))
        text_width = c_right - c_left
    beside = caption is None or m + bar_width + 2 * m + text_width + m <= plan.width
    width = max(plan.width, m + bar_width + m, m + text_width + m)
    height = plan.height + m + line + m + (0 if beside else line + m)
    canvas = Image.new("RGB", (width, height), (255, 255, 255))
    canvas.paste(plan, (0, 0))
    draw = ImageDraw.Draw(canvas)
    y = plan.height + m  # the text line's top
    draw.line([(m, y + line - 2), (m + ppm, y + line - 2)], fill=TEXT, width=3)
    draw.text((m + ppm + 5 - left, y - top), "1 m", fill=TEXT, font=font)
    if caption:
        x, cy = (width - m - text_width, y) if beside else (m, y + line + m)
        draw.text((x - c_left, cy - top), caption, fill=TEXT, font=font)
    return canvas


def scene_picture(
    layout: SceneLayout | None,
    navigable: np.ndarray,
    origin: tuple[float, float],
    cell_size: float,
    pixels_per_metre: float = 40,
    caption: bool = True,
    keep_clear: Sequence[Sequence[float]] = (),
) -> Image.Image:
    """A top-down RGB picture: navigable cells light, the rest darker, the layout drawn on top;
    under it, outside the plan, a white footer with a 1 m scale bar and the scene id (if
    ``caption``).

    The plan is the picture's top-left ``round(cols * cell_size * pixels_per_metre)`` ×
    ``round(rows * cell_size * pixels_per_metre)`` pixels (:func:`world_to_pixel`); the
    footer adds height, and width where the id is wider than the plan.
    """
    grid = np.asarray(navigable, dtype=bool)
    if grid.ndim != 2:
        raise ValueError(f"navigable must be a 2-D array, got shape {grid.shape}")
    frame = picture_frame(grid, origin, cell_size, pixels_per_metre)
    colours = np.where(grid[..., None], np.array(NAVIGABLE, np.uint8), np.array(BLOCKED, np.uint8))
    if layout is not None:
        colours[~_under_floor(layout, grid.shape, origin, cell_size) & ~grid] = OUTSIDE
    # Row 0 is the lowest y, so flip it to the bottom of the picture.
    image = Image.fromarray(np.ascontiguousarray(colours[::-1]), mode="RGB")
    image = image.resize(frame.image_size, Image.Resampling.NEAREST)
    draw = ImageDraw.Draw(image)
    font = label_font(frame)
    if layout is not None:
        draw_layout(draw, layout, frame, keep_clear)
    scene_id = layout.scene_id if layout is not None and caption else None
    return _with_footer(image, frame, scene_id, font)


def gps_to_world(gps: np.ndarray, episode: Episode) -> np.ndarray:
    """World (x, y) of GPS readings (start frame: x ahead, y left of the start pose)."""
    c, s = math.cos(episode.start_yaw), math.sin(episode.start_yaw)
    x0, y0 = episode.start_position[:2]
    return np.stack([x0 + c * gps[:, 0] - s * gps[:, 1], y0 + s * gps[:, 0] + c * gps[:, 1]], -1)
