"""The frames of an episode video: the agent's RGB and depth beside a top-down map, captioned.

Layout (pixels; P = the panel height, the camera height but at least 256)::

    +-----------+-----------+---------+
    |    RGB    |   depth   |   map   |   P high: camera images scaled to P (nearest),
    +-----------+-----------+---------+   the map fitted into P x 2P, centred
    | agent, episode, scene            |
    | step, action, current goal, distance, goals found
    | what just happened (FOUND right / wrong, a collision, the end)

The map is the floor plan of :func:`multion.scenes.viz.scene_picture` with the goals numbered in the
order they must be found (the current one ringed, found ones ticked), the path so far in orange
and the agent as a triangle pointing where it looks. Frame sizes are even (H.264's 4:2:0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from multion.config.episode import Episode
from multion.scenes.registry import is_mesh_scene, layout_for
from multion.scenes.viz import PictureFrame, picture_frame, scene_picture, world_to_pixel
from multion.sim.navgrid import NavGrid
from multion.sim.pictures import AGENT_PATH, OUTLINE
from multion.video.replay import StepView
from multion_client.constants import GOAL_RGBA, Action

MIN_PANEL = 256
MAP_MARGIN = 6
MAX_MAP_ASPECT = 2.0
"""The map panel is P high and twice P wide whatever the house's shape, so that every video of a
run (of a track: one camera size) has one frame size: a player or page that lays out one film
does not jump at the next. A house wider than that is scaled down to fit."""
CAPTION_FONT_SIZE = 14
CAPTION_LINES = 3
BACKGROUND = (255, 255, 255)
RIGHT = (20, 140, 50)
WRONG = (200, 30, 30)
HIGHLIGHT = (255, 200, 0)
PANEL_NAMES = ("RGB", "depth", "map")
ENDING = ("progress", "spl", "ppl")
"""The metrics the last frame's caption gives."""


def even(value: float) -> int:
    """The nearest even whole number at least 2 (yuv420p halves both sides)."""
    return max(2, 2 * round(value / 2))


class FrameComposer:
    """Draws the frames of one episode, in order: the path accumulates from frame to frame."""

    def __init__(
        self,
        episode: Episode,
        grid: NavGrid,
        camera_size: tuple[int, int],
        title: str,
        goal_names: Sequence[str],
        max_steps: int,
        depth_scale: float = 1.0,
    ) -> None:
        width, height = camera_size
        self.episode = episode
        self.title = title
        self.goal_names = tuple(goal_names[g.category] for g in episode.goals)
        self.max_steps = max_steps
        self.depth_scale = depth_scale
        self.panel = even(max(MIN_PANEL, height))
        self.view_size = (even(width * self.panel / height), self.panel)
        self.font = ImageFont.load_default(size=CAPTION_FONT_SIZE)
        self.line_height = CAPTION_FONT_SIZE + 5
        caption = even(CAPTION_LINES * self.line_height + 10)
        self._map_frame, self._trail = self._floor_plan(grid)
        self.size = (2 * self.view_size[0] + self.map_width, self.panel + caption)
        self._last_point: tuple[float, float] | None = None

    # ------------------------------------------------------------------ the whole frame
    def frame(self, view: StepView) -> np.ndarray:
        """The (height, width, 3) uint8 frame of ``view``."""
        canvas = Image.new("RGB", self.size, BACKGROUND)
        rgb = Image.fromarray(np.ascontiguousarray(view.rgb[..., :3]), "RGB")
        canvas.paste(rgb.resize(self.view_size, Image.Resampling.NEAREST), (0, 0))
        depth = np.clip(np.asarray(view.depth, np.float32)[..., 0] * self.depth_scale, 0, 1)
        grey = Image.fromarray((depth * 255).astype(np.uint8), "L").convert("RGB")
        canvas.paste(grey.resize(self.view_size, Image.Resampling.NEAREST), (self.view_size[0], 0))
        canvas.paste(self._map(view), (2 * self.view_size[0], 0))
        draw = ImageDraw.Draw(canvas)
        for index, name in enumerate(PANEL_NAMES):
            self._panel_name(draw, index * self.view_size[0], name)
        event, colour = self.event(view)
        if colour is not None:  # a FOUND: the agent's view framed in its result's colour
            width = 4
            box = [width // 2, width // 2, self.view_size[0] - width // 2, self.panel - width // 2]
            draw.rectangle(box, outline=colour, width=width)
        lines = [(self.title, OUTLINE), (self.status(view), OUTLINE), (event, colour or OUTLINE)]
        for number, (text, ink) in enumerate(lines):
            y = self.panel + 5 + number * self.line_height
            draw.text((8, y), text, fill=ink, font=self.font)
        return np.asarray(canvas)

    # ------------------------------------------------------------------ captions
    def status(self, view: StepView) -> str:
        """Step, action, the current goal and its distance, goals found."""
        action = "start" if view.action is None else Action(view.action).name
        found = f"found {view.goals_found}/{len(self.goal_names)}"
        if view.goals_found >= len(self.goal_names):
            goal = "every goal found"
        else:
            number = view.goals_found + 1
            goal = (
                f"goal {number} ({self.goal_names[number - 1]}) {view.distance_to_goal:.2f} m away"
            )
        return f"step {view.step}/{self.max_steps}   {action:<12}  {goal}   {found}"

    def event(self, view: StepView) -> tuple[str, tuple[int, int, int] | None]:
        """What just happened, and the colour of a FOUND's result (None otherwise)."""
        ending = ""
        if end := view.metrics.get("end_reason"):
            scores = ", ".join(f"{key} {float(view.metrics.get(key, 0)):.2f}" for key in ENDING)
            ending = f"   end: {end}; {scores}"
        if view.found_correct:
            name = self.goal_names[view.goals_found - 1]
            return f"FOUND: right, goal {view.goals_found} ({name}){ending}", RIGHT
        if view.found_wrong:
            return (
                f"FOUND: wrong, the current goal is {view.distance_to_goal:.2f} m away{ending}",
                WRONG,
            )
        if view.collided:
            return f"bumped into an obstacle{ending}", None
        return ending.strip(), None

    def _panel_name(self, draw: ImageDraw.ImageDraw, x: int, text: str) -> None:
        left, top, right, bottom = draw.textbbox((0, 0), text, font=self.font)
        box = [x + 6, 6, x + 12 + right - left, 12 + bottom - top]
        draw.rectangle(box, fill=BACKGROUND)
        draw.text((x + 9 - left, 9 - top), text, fill=OUTLINE, font=self.font)

    # ------------------------------------------------------------------ the map
    def _floor_plan(self, grid: NavGrid) -> tuple[PictureFrame, Image.Image]:
        """The frame and the picture of the scene, fitted into its panel and centred."""
        rows, cols = grid.shape
        self.map_width = even(MAX_MAP_ASPECT * self.panel)
        side = (self.map_width - 2 * MAP_MARGIN, self.panel - 2 * MAP_MARGIN)
        ppm = min(side[0] / (cols * grid.cell_size), side[1] / (rows * grid.cell_size))
        scene_id = self.episode.scene_id
        layout = None if is_mesh_scene(scene_id) else layout_for(scene_id)
        frame = picture_frame(grid.navigable, grid.origin, grid.cell_size, ppm)
        plan = scene_picture(layout, grid.navigable, grid.origin, grid.cell_size, ppm, False)
        plan = plan.crop((0, 0, *frame.image_size))  # the plan without its footer (scale bar)
        panel = Image.new("RGB", (self.map_width, self.panel), BACKGROUND)
        offset = ((self.map_width - plan.width) // 2, (self.panel - plan.height) // 2)
        panel.paste(plan, offset)
        # the panel's own frame: world_to_pixel then gives pixels of the panel
        shifted = PictureFrame(
            (frame.origin[0] - offset[0] / ppm, frame.origin[1] - offset[1] / ppm),
            (self.map_width / ppm, self.panel / ppm),
            ppm,
        )
        return shifted, panel

    def _map(self, view: StepView) -> Image.Image:
        frame = self._map_frame
        point = world_to_pixel(float(view.position[0]), float(view.position[1]), frame)
        width = max(2, round(frame.pixels_per_metre * 0.08))
        if self._last_point is not None and view.step > 0:
            ImageDraw.Draw(self._trail).line([self._last_point, point], AGENT_PATH, width)
        self._last_point = point
        picture = self._trail.copy()
        draw = ImageDraw.Draw(picture)
        self._goals(draw, view.goals_found)
        self._agent(draw, point, view.yaw)
        return picture

    def _goals(self, draw: ImageDraw.ImageDraw, found: int) -> None:
        frame = self._map_frame
        radius = max(7.0, frame.pixels_per_metre * 0.3)
        for index, goal in enumerate(self.episode.goals):
            x, y = world_to_pixel(goal.position[0], goal.position[1], frame)
            if index == found:  # the current goal: a thick ring around it
                ring = radius + 4
                draw.ellipse([x - ring, y - ring, x + ring, y + ring], outline=HIGHLIGHT, width=4)
            fill = tuple(round(255 * c) for c in GOAL_RGBA[goal.category][:3])
            draw.ellipse(
                [x - radius, y - radius, x + radius, y + radius],
                fill=fill,
                outline=OUTLINE,
                width=2,
            )
            ink = BACKGROUND if sum(fill) < 300 else OUTLINE
            if index < found:  # found: ticked
                tick = [(x - radius * 0.5, y), (x - radius * 0.1, y + radius * 0.45)]
                tick.append((x + radius * 0.55, y - radius * 0.45))
                draw.line(tick, fill=ink, width=max(2, round(radius / 4)))
                continue
            text = str(index + 1)
            left, top, right, bottom = draw.textbbox((0, 0), text, font=self.font)
            at = (x - (right - left) / 2 - left, y - (bottom - top) / 2 - top)
            draw.text(at, text, fill=ink, font=self.font)

    def _agent(self, draw: ImageDraw.ImageDraw, point: tuple[float, float], yaw: float) -> None:
        size = max(9.0, self._map_frame.pixels_per_metre * 0.5)
        x, y = point
        # world yaw is counter-clockwise from +x; pixel rows grow downwards
        corners = [
            (x + size * math.cos(yaw + a), y - size * math.sin(yaw + a)) for a in (0.0, 2.5, -2.5)
        ]
        corners[1:] = [(x + (cx - x) * 0.6, y + (cy - y) * 0.6) for cx, cy in corners[1:]]
        draw.polygon(corners, fill=AGENT_PATH, outline=OUTLINE)
