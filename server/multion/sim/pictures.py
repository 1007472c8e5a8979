"""Top-down pictures of played episodes, in the style of the paper's Figure 3.

The scene (floor plan, walls, furniture) comes from :func:`multion.scenes.viz.scene_picture`;
on top: the shortest path through the goals in green, the agent's path in orange, the start as
an orange square, and the goals as circles in their own colours, numbered in the order they must
be found. The scene layout and the shortest path are recomputed from the episode (an evaluation
client never sees the server's simulator); the agent's path is rebuilt from its GPS readings
(:func:`multion.scenes.viz.gps_to_world`). Used by ``multion eval`` and by the leaderboard's run
pages.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from multion.config.episode import Episode
from multion.scenes.registry import is_mesh_scene, layout_for
from multion.scenes.viz import (
    PictureFrame,
    label_font,
    picture_frame,
    scene_picture,
    world_to_pixel,
)
from multion.sim.geodesic import distance_field, shortest_path
from multion.sim.simulator import Simulator
from multion_client.constants import GOAL_RGBA

AGENT_PATH = (245, 130, 20)
SHORTEST_PATH = (30, 160, 60)
OUTLINE = (20, 20, 20)
GOAL_RADIUS = 0.05


def shortest_route(simulator: Simulator, episode: Episode) -> list[np.ndarray]:
    """World points of a shortest path start → g1 → g2 → …, one array per leg."""
    grid = simulator.load_scene(episode.scene_id)
    legs = []
    previous = np.asarray(episode.start_position[:2], dtype=np.float64)
    for goal in episode.goals:
        target = np.asarray(goal.position[:2], dtype=np.float64)
        field = distance_field(grid, target, GOAL_RADIUS)
        leg = shortest_path(grid, field, previous)
        legs.append(np.vstack([leg, target[None, :]]))
        previous = target
    return legs


def episode_picture(
    episode: Episode,
    path: np.ndarray,
    metrics: dict[str, Any],
    simulator: Simulator | None = None,
    pixels_per_metre: float = 40,
    label: str | None = None,
) -> Image.Image:
    """The picture of one episode; ``path`` is the agent's world (x, y) positions, in order.

    ``label`` replaces the episode and scene ids in the captions (hidden episodes keep theirs
    secret)."""
    own = simulator is None
    sim = simulator or Simulator()
    try:
        grid = sim.load_scene(episode.scene_id)
        route = shortest_route(sim, episode)
    finally:
        if own:
            sim.close()
    layout = None if is_mesh_scene(episode.scene_id) else layout_for(episode.scene_id)
    frame = picture_frame(grid.navigable, grid.origin, grid.cell_size, pixels_per_metre)
    image = scene_picture(
        layout, grid.navigable, grid.origin, grid.cell_size, pixels_per_metre,
        caption=label is None, keep_clear=_marker_boxes(episode, frame),
    )  # fmt: skip
    draw = ImageDraw.Draw(image)
    width = max(2, round(pixels_per_metre * 0.06))
    for leg in route:
        _polyline(draw, leg, frame, SHORTEST_PATH, width)
    _polyline(draw, path, frame, AGENT_PATH, width)
    _start(draw, episode, frame)
    _goals(draw, episode, frame)
    return _with_legend(image, label or episode.episode_id, metrics, label_font(frame))


def _polyline(
    draw: ImageDraw.ImageDraw,
    points: np.ndarray,
    frame: PictureFrame,
    colour: tuple[int, int, int],
    width: int,
) -> None:
    pixels = [world_to_pixel(float(x), float(y), frame) for x, y in points]
    if len(pixels) >= 2:
        draw.line(pixels, fill=colour, width=width, joint="curve")


def _marker_boxes(episode: Episode, frame: PictureFrame) -> list[list[float]]:
    """Pixel boxes of the start and goal markers (with a small margin): room labels avoid them."""
    reach = frame.pixels_per_metre * 0.25
    points = [episode.start_position[:2], *(g.position[:2] for g in episode.goals)]
    boxes = []
    for point in points:
        x, y = world_to_pixel(float(point[0]), float(point[1]), frame)
        boxes.append([x - reach, y - reach, x + reach, y + reach])
    return boxes


def _start(draw: ImageDraw.ImageDraw, episode: Episode, frame: PictureFrame) -> None:
    x, y = world_to_pixel(*episode.start_position[:2], frame)
    half = frame.pixels_per_metre * 0.15
    draw.rectangle([x - half, y - half, x + half, y + half], fill=AGENT_PATH, outline=OUTLINE)


def _goals(draw: ImageDraw.ImageDraw, episode: Episode, frame: PictureFrame) -> None:
    font = label_font(frame)
    radius = frame.pixels_per_metre * 0.2
    for number, goal in enumerate(episode.goals, start=1):
        x, y = world_to_pixel(*goal.position[:2], frame)
        fill = _rgb(GOAL_RGBA[goal.category])
        draw.ellipse([x - radius, y - radius, x + radius, y + radius], fill=fill, outline=OUTLINE)
        text = str(number)
        left, top, right, bottom = draw.textbbox((0, 0), text, font=font)
        ink = (255, 255, 255) if sum(fill) < 300 else OUTLINE
        draw.text(
            (x - (right - left) / 2 - left, y - (bottom - top) / 2 - top), text, fill=ink, font=font
        )


def _with_legend(
    image: Image.Image, label: str, metrics: dict[str, Any], font: ImageFont.ImageFont | Any
) -> Image.Image:
    """The picture under a white strip with the episode's label and headline metrics (above
    the map, not on it: small houses would be hidden under the text)."""
    lines = [
        label,
        "success {:.0f}  progress {:.2f}".format(
            float(metrics.get("success", 0)), float(metrics.get("progress", 0))
        ),
        "SPL {:.2f}  PPL {:.2f}  steps {}".format(
            float(metrics.get("spl", 0)), float(metrics.get("ppl", 0)), metrics.get("steps", "?")
        ),
    ]
    text = "\n".join(lines)
    probe = ImageDraw.Draw(image)
    # typed as floats; whole pixels here (the text starts at a whole pixel)
    left, top, right, bottom = (int(v) for v in probe.multiline_textbbox((0, 0), text, font=font))
    strip = bottom - top + 12
    canvas = Image.new(
        "RGB", (max(image.width, right - left + 12), image.height + strip), (255, 255, 255)
    )
    ImageDraw.Draw(canvas).multiline_text((6 - left, 6 - top), text, fill=OUTLINE, font=font)
    canvas.paste(image, (0, strip))
    return canvas


def _rgb(rgba: Sequence[float]) -> tuple[int, int, int]:
    return (round(255 * rgba[0]), round(255 * rgba[1]), round(255 * rgba[2]))
