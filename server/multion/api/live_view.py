"""What the live view of a session shows: its last answer (reset or step) drawn as one picture.

The picture puts the environment's ``rgb`` and ``depth`` (those the session asked for) beside a
top-down map of the house: walls and furniture, the goals numbered in order (the current one
ringed) and, when the session has ``gps`` (and ``compass``), the agent where it stands. Nothing
is asked of the simulator workers: the session's last answer is decoded here, and the map is
drawn from the scene's layout (procedural houses; a mesh scene has no map).
"""

from __future__ import annotations

import functools
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from multion.api.sessions import Session
from multion.config.codec import session_config_from_dict
from multion.config.datasets import DatasetError, load_dataset, packaged_dataset_path
from multion.config.episode import Episode
from multion.config.ranges import ConfigError
from multion.scenes.registry import is_mesh_scene, layout_for
from multion.scenes.viz import NAVIGABLE, PictureFrame, draw_layout, gps_to_world, world_to_pixel
from multion_client.constants import GOAL_RGBA, Action
from multion_client.protocol import decode

PANEL = 256
"""Height of every panel, pixels (camera images are scaled to it)."""
BACKGROUND = (255, 255, 255)
OUTLINE = (20, 20, 20)
AGENT = (245, 130, 20)
HIGHLIGHT = (255, 200, 0)
FONT = ImageFont.load_default(size=14)


@dataclass(frozen=True)
class LiveStep:
    """One environment of a session as its last answer left it."""

    observation: dict[str, Any]
    info: dict[str, Any]
    action: int | None
    trail: tuple[tuple[float, float], ...] = ()
    """Its ``gps`` readings since its episode began (the path the map draws)."""

    def state(self) -> dict[str, Any]:
        """What the page prints: episode, step, action and the metrics (JSON-ready)."""
        metrics = {k: _plain(v) for k, v in dict(self.info.get("metrics", {})).items()}
        return {
            "started": True,
            "episode_id": self.info.get("episode_id"),
            "scene_id": self.info.get("scene_id"),
            "step": metrics.get("steps", 0),
            "action": None if self.action is None else Action(self.action).name,
            "metrics": metrics,
            "sensors": sorted(self.observation),
        }


def latest_step(session: Session, env: int) -> LiveStep | None:
    """Environment ``env`` of the session's last answer; None before its first reset."""
    if not session.latest:
        return None
    answer = decode(session.latest)
    action = session.last_actions[env] if session.last_actions else None
    info = answer["infos"][env]
    trail: tuple[tuple[float, float], ...] = ()
    if env < len(session.trails) and session.trails[env].episode_id == info.get("episode_id"):
        trail = tuple(session.trails[env].points)
    return LiveStep(answer["observations"][env], info, action, trail)


PARTS = ("all", "views", "map")
"""What a picture holds: every panel side by side, the camera views (RGB, depth), the map
(the page shows the last two apart, so that a narrow screen shows each at its full width)."""


def picture(session: Session, step: LiveStep, part: str = "all") -> bytes:
    """The PNG of ``step``: RGB, depth and the map, side by side, as far as they exist (or only
    the views, or only the map: ``part``)."""
    if part not in PARTS:
        raise ValueError(f"part must be one of {', '.join(PARTS)}, got {part!r}")
    panels: list[Image.Image | None] = []
    if part in ("all", "views"):
        panels += [_camera(step.observation.get("rgb")), _depth(step.observation.get("depth"))]
    if part in ("all", "map"):
        episode = episode_of(session.config, str(step.info.get("episode_id", "")))
        panels.append(_map(step, episode))
    shown = [p for p in panels if p is not None]
    canvas = Image.new("RGB", (sum(p.width for p in shown) or PANEL, PANEL), BACKGROUND)
    x = 0
    for panel in shown:
        canvas.paste(panel, (x, 0))
        x += panel.width
    buffer = io.BytesIO()
    canvas.save(buffer, format="PNG")
    return buffer.getvalue()


def _camera(rgb: Any) -> Image.Image | None:
    if not isinstance(rgb, np.ndarray) or rgb.ndim != 3:
        return None
    image = Image.fromarray(np.ascontiguousarray(rgb[..., :3]).astype(np.uint8), "RGB")
    return image.resize(
        (round(image.width * PANEL / image.height), PANEL), Image.Resampling.NEAREST
    )


def _depth(depth: Any) -> Image.Image | None:
    if not isinstance(depth, np.ndarray) or depth.ndim != 3:
        return None
    scaled = np.asarray(depth[..., 0], np.float32)
    scaled = scaled / max(1.0, float(scaled.max()))  # metres when the session did not normalise
    grey = Image.fromarray((np.clip(scaled, 0, 1) * 255).astype(np.uint8), "L").convert("RGB")
    return _camera(np.asarray(grey))


def _map(step: LiveStep, episode: Episode | None) -> Image.Image | None:
    scene_id = str(step.info.get("scene_id", ""))
    if not scene_id or is_mesh_scene(scene_id):
        return None
    layout = layout_for(scene_id)
    floors = [b for b in layout.boxes if b.kind == "floor"] or list(layout.boxes)
    x0 = min(b.min_corner[0] for b in floors)
    y0 = min(b.min_corner[1] for b in floors)
    x1 = max(b.max_corner[0] for b in floors)
    y1 = max(b.max_corner[1] for b in floors)
    width, height = x1 - x0, y1 - y0
    ppm = min(2 * PANEL / width, PANEL / height)
    frame = PictureFrame((x0, y0), (width, height), ppm)
    image = Image.new("RGB", frame.image_size, BACKGROUND)
    draw = ImageDraw.Draw(image)
    for box in floors:
        (a, b, _), (c, d, _) = box.min_corner, box.max_corner
        (left, bottom), (right, top) = world_to_pixel(a, b, frame), world_to_pixel(c, d, frame)
        draw.rectangle([left, top, right, bottom], fill=NAVIGABLE)
    draw_layout(draw, layout, frame)
    if episode is not None:
        found = int(step.info.get("metrics", {}).get("goals_found", 0))
        _goals(draw, episode, frame, found)
        _trail(draw, step.trail, episode, frame)
        gps = step.observation.get("gps")
        if isinstance(gps, np.ndarray):
            x, y = gps_to_world(np.asarray(gps, np.float64).reshape(1, 2), episode)[0]
            compass = step.observation.get("compass")
            yaw = episode.start_yaw + (float(np.ravel(compass)[0]) if compass is not None else 0.0)
            _agent(draw, world_to_pixel(float(x), float(y), frame), yaw, ppm)
    return image


def _trail(
    draw: ImageDraw.ImageDraw,
    trail: tuple[tuple[float, float], ...],
    episode: Episode,
    frame: PictureFrame,
) -> None:
    """The path walked in this episode, as the videos draw it (the agent's colour)."""
    if len(trail) < 2:
        return
    world = gps_to_world(np.asarray(trail, np.float64), episode)
    points = [world_to_pixel(float(x), float(y), frame) for x, y in world]
    width = max(2, round(frame.pixels_per_metre * 0.08))
    draw.line(points, fill=AGENT, width=width, joint="curve")


def _goals(draw: ImageDraw.ImageDraw, episode: Episode, frame: PictureFrame, found: int) -> None:
    radius = max(6.0, frame.pixels_per_metre * 0.3)
    for index, goal in enumerate(episode.goals):
        x, y = world_to_pixel(goal.position[0], goal.position[1], frame)
        if index == found:
            ring = radius + 4
            draw.ellipse([x - ring, y - ring, x + ring, y + ring], outline=HIGHLIGHT, width=4)
        fill = tuple(round(255 * c) for c in GOAL_RGBA[goal.category][:3])
        draw.ellipse([x - radius, y - radius, x + radius, y + radius], fill=fill, outline=OUTLINE)
        ink = BACKGROUND if sum(fill) < 300 else OUTLINE
        if index < found:  # found: ticked
            tick = [(x - radius * 0.5, y), (x - radius * 0.1, y + radius * 0.45)]
            draw.line([*tick, (x + radius * 0.55, y - radius * 0.45)], fill=ink, width=3)
        else:
            draw.text((x, y), str(index + 1), fill=ink, font=FONT, anchor="mm")


def _agent(draw: ImageDraw.ImageDraw, at: tuple[float, float], yaw: float, ppm: float) -> None:
    size, (x, y) = max(9.0, ppm * 0.5), at
    tip = (x + size * math.cos(yaw), y - size * math.sin(yaw))
    back = [
        (x + 0.6 * size * math.cos(yaw + a), y - 0.6 * size * math.sin(yaw + a))
        for a in (2.5, -2.5)
    ]
    draw.polygon([tip, *back], fill=AGENT, outline=OUTLINE)


@functools.lru_cache(maxsize=32)
def _dataset(path: str, num_goals: int) -> dict[str, Episode]:
    return {e.episode_id: e for e in load_dataset(Path(path), num_goals)}


def episode_of(config: dict[str, Any], episode_id: str) -> Episode | None:
    """The episode ``episode_id`` of a session's config (inline, its dataset or the packaged
    one), or None (online training episodes are sampled in the worker and kept there)."""
    try:
        env_config, inline = session_config_from_dict(config)
    except ConfigError:
        return None
    if inline is not None:
        return next((e for e in inline if e.episode_id == episode_id), None)
    num_goals = env_config.task.num_goals
    try:
        path = env_config.dataset or packaged_dataset_path(
            num_goals, env_config.split, env_config.task.num_distractors
        )
        return _dataset(str(path), num_goals).get(episode_id)
    except (DatasetError, OSError, ValueError):
        return None


def _plain(value: Any) -> Any:
    """numpy numbers and arrays as JSON's."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value
