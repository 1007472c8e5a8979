"""The explorer as it was before issue 23 made it faster: the oracle for its speed-up.

Only the parts that were rewritten are here, verbatim: :class:`ReferenceExplorerAgent` is
:class:`~multion_agents.baselines.explorer.ExplorerAgent` with those parts put back. Two uses, nothing else:
``tests/agents/test_explorer_speed.py`` checks that both take the same decisions on the same
inputs, and ``multion bench --only explorer`` measures the speed-up on the same observations.
The action sequences pinned by ``tests/agents/test_explorer_actions.py`` were recorded with
this code.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from multion_agents.agent import Observation
from multion_agents.baselines.explorer import _CROSS, GOAL_RADII, ExplorerAgent
from multion_agents.baselines.mapping import (
    _CODE_TO_CATEGORY,
    OFF_LEVEL,
    ON_LEVEL,
    CameraModel,
    DepthProjector,
    Detections,
    SemanticMap,
)
from multion_agents.baselines.navigation import (
    Motion,
    StartFrameGrid,
    _starting,
    _turned,
    bounding_box,
    cells_ahead,
    interpolate,
    snap_heading,
    step_points,
)
from multion_client.constants import NUM_CATEGORIES, Action

_WHITE_SPREAD = 0


def reference_detect_goals(rgb: np.ndarray, min_pixels: int = 3) -> Detections:
    """The pixels of each goal colour in an (H, W, 3) uint8 image (categories with enough)."""
    red, green, blue = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    # channel by channel: much faster than reducing over a last axis of length 3
    low = np.minimum(np.minimum(red, green), blue)
    high = np.maximum(np.maximum(red, green), blue)
    # cheap pre-filter: some channel is off (no scene colour has one), or bright balanced grey
    rows, cols = np.nonzero(
        (low <= OFF_LEVEL) | ((low >= ON_LEVEL) & (high - low <= _WHITE_SPREAD))
    )
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


def reference_goal_shaped(
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
        mask = np.zeros(depth.shape[:2], dtype=bool)
        mask[rows, cols] = True
        labels, count = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
        blob = labels[rows, cols]
        keep = np.zeros(len(rows), dtype=bool)
        for label in range(1, count + 1):
            inside = blob == label
            z = camera.metres(float(np.median(depth[rows[inside], cols[inside], 0])))
            span = int(cols[inside].max() - cols[inside].min()) + 1
            keep |= inside & (span * z / focal <= max_width)
        if keep.sum() > 0:
            kept[category] = (rows[keep], cols[keep])
    return kept


def reference_choose_action(
    grid: StartFrameGrid,
    field: np.ndarray,
    passable: np.ndarray,
    position: np.ndarray,
    heading: float,
    motion: Motion = Motion(),
    turn_cost: float = 0.02,
) -> int | None:
    """The turn or forward step that starts the best one-step move down ``field``.

    Each reachable heading is scored by the field at the end of a forward step in that direction
    (only if the whole step stays on ``passable`` cells), plus ``turn_cost`` metres per turn
    needed, so the agent does not spin for a centimetre. Returns None when no step goes downhill.
    """
    here = interpolate(grid, field, position)
    n = motion.headings
    angle, index = snap_heading(heading, motion)
    best_value, best_turns = here - 1e-6, None
    for k in range(n):
        turns = k if k <= n // 2 else k - n  # positive: turn left (counter-clockwise)
        points = step_points(position, _turned(angle, index, turns, motion), motion)
        if not grid.lookup(passable, points, outside=False).all():
            continue
        value = interpolate(grid, field, points[-1]) + turn_cost * abs(turns)
        if value < best_value:
            best_value, best_turns = value, turns
    return _starting(best_turns)


class ReferenceDepthProjector(DepthProjector):
    def points(
        self, depth: np.ndarray, position: np.ndarray, heading: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sampled pixels as ``(xy (h, w, 2), height above floor (h, w), metres (h, w))``.

        ``depth`` is the normalised sensor image (H, W, 1) in [0, 1].
        """
        cam = self.camera
        sampled = depth[self.rows][:, self.cols, 0].astype(np.float64)
        z = cam.metres(sampled)
        forward, left = z, -self.right * z
        c, s = math.cos(heading), math.sin(heading)
        xy = np.stack(
            [position[0] + c * forward - s * left, position[1] + s * forward + c * left], axis=-1
        )
        return xy, cam.height + self.up * z, z


class ReferenceSemanticMap(SemanticMap):
    def mark_free_disc(self, position: np.ndarray, radius: float) -> None:
        """Where the agent stands is free (the camera never sees the floor under its feet)."""
        cells = int(math.ceil(radius / self.grid.cell_size))
        offsets = np.arange(-cells, cells + 1) * self.grid.cell_size
        ox, oy = np.meshgrid(offsets, offsets)
        keep = np.hypot(ox, oy) <= radius
        points = position[None, :] + np.stack([ox[keep], oy[keep]], axis=-1)
        self._set(points, self.free, True)

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
        xy, height, z = projector.points(depth, position, heading)
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
        before = int(self.obstacle.sum()), int(self.free.sum())
        self._set(xy[obstacle], self.obstacle, True)
        self._set(xy[floor], self.free, True)
        self._carve(projector, xy, obstacle, near, floor | saturated, position, heading)
        self.changed = (int(self.obstacle.sum()), int(self.free.sum())) != before
        return self._remember_goals(projector, depth, detections, position, heading)

    def _carve(
        self,
        projector: DepthProjector,
        xy: np.ndarray,
        obstacle: np.ndarray,
        near: np.ndarray,
        open_: np.ndarray,
        position: np.ndarray,
        heading: float,
    ) -> None:
        """Free space along each image column, from the agent to the first obstacle it sees
        (nothing in a column with a surface nearer than the depth range)."""
        reach = np.hypot(*(xy - position).transpose(2, 0, 1))
        obstacle_reach = np.where(obstacle, reach, np.inf).min(axis=0)
        obstacle_reach[near.any(axis=0)] = 0.0
        open_reach = np.where(open_, reach, 0.0).max(axis=0)
        limit = np.minimum(obstacle_reach - 0.1, open_reach)  # (columns,)
        step = self.settings.carve_step
        distances = np.arange(step, float(limit.max(initial=0.0)), step)
        if len(distances) == 0:
            return
        bearings = heading - np.arctan(projector.right[0])  # left of the heading is positive
        directions = np.stack([np.cos(bearings), np.sin(bearings)], axis=-1)
        points = position + distances[:, None, None] * directions[None, :, :]
        self._set(points[distances[:, None] < limit[None, :]], self.free, True)

    def _set(self, points: np.ndarray, layer: np.ndarray, value: bool) -> None:
        rows, cols = self.grid.to_cell(points)
        ok = (rows >= 0) & (rows < self.grid.size) & (cols >= 0) & (cols < self.grid.size)
        layer[rows[ok], cols[ok]] = value


class ReferenceExplorerAgent(ExplorerAgent):
    """The explorer with the parts issue 23 rewrote as they were."""

    def reset(self) -> None:
        super().reset()
        self.map = ReferenceSemanticMap(self.grid)

    def _perceive(self, observation: Observation, position: np.ndarray, heading: float) -> set[int]:
        depth, rgb = observation["depth"], observation["rgb"]
        if self._projector is None:
            stride = max(1, depth.shape[1] // self.settings.depth_rays)
            self._projector = ReferenceDepthProjector(depth.shape[:2], self.camera, stride)
        detections = reference_goal_shaped(reference_detect_goals(rgb), depth, self.camera)
        self.map.integrate(self._projector, depth, detections, position, heading)
        self.map.mark_free_disc(position, 0.15)
        return set(detections)

    def _track_motion(self, position: np.ndarray, heading: float) -> None:
        """Learn from the last action: refused steps, cells stood in, turning without end."""
        moved = self._last_position is None or not np.allclose(
            position, self._last_position, atol=1e-4
        )
        if self._last_action == Action.MOVE_FORWARD and not moved:
            self._blocked[cells_ahead(self.grid, position, heading, self.motion)] = True
            self._field = None
            self.map.changed = True
        row, col = (int(v) for v in self.grid.to_cell(position))
        if not self._visited[row, col]:
            self._visited[row, col] = True
            self._around_path |= self._disc(position, self.settings.close_range)
            self.map.changed = True
        self._still = 0 if moved else self._still + 1
        if self._still > 2 * self.motion.headings and self._spin == 0:
            # two full circles without moving: whatever the plan says, it is not working; forget
            # the refusals around here (the simulator will refuse again if it must)
            self._still = 0
            self._field = None
            self._blocked &= ~self._disc(position, 0.5)
            self.map.changed = True
            if self._target == ("frontier", -1):
                self._give_up_near(position)
            else:
                # stuck on the way to a remembered goal (pressing against a doorway the map
                # thinks is open): explore elsewhere for a while, which finds another way in
                self._detour = self.settings.detour_steps

    def _refresh_passable(self) -> None:
        """Passable = not within one cell of a seen obstacle, and not refused by the simulator.

        Optimistic: unknown cells count as passable, since the camera looks where the agent goes.
        The dilation runs only over the box around the obstacles, to stay cheap every step.
        """
        if self._tight > 0:  # walled in by the margin: only the obstacles themselves block
            inflated = self.map.obstacle
        else:
            r0, r1, c0, c1 = bounding_box(self.map.obstacle, margin=2)
            inflated = np.zeros_like(self._blocked)
            inflated[r0:r1, c0:c1] = ndimage.binary_dilation(self.map.obstacle[r0:r1, c0:c1])
        # where the agent has been is passable, whatever the dilation says
        self._passable = ~(inflated | self._blocked) | (self._visited & ~self._blocked)

    def _plan(self, position: np.ndarray) -> None:
        known = self.map.explored() | self._disc(position, 1.0)
        if self._target_point is not None:
            known |= self._disc(self._target_point, 1.0)
        box = bounding_box(known, margin=8)
        self._since_plan = 0
        if self._target is None or self._target[0] != "goal":
            self._field = self._field_to(self._frontier(self._passable), box)
            if self._tight == 0 and not np.isfinite(interpolate(self.grid, self._field, position)):
                # no frontier reachable through the margin kept round seen obstacles (a
                # cluttered spot walls the agent in)
                self._squeeze()
                self._field = self._field_to(self._frontier(self._passable), box)
            return
        assert self._target_point is not None
        while True:
            ring = self._ring(self._target_point, GOAL_RADII[self._aim])
            self._field = self._field_to(ring, box)
            reachable = np.isfinite(interpolate(self.grid, self._field, position))
            if reachable or self._aim == len(GOAL_RADII) - 1:
                return
            self._aim += 1

    def _frontier(self, passable: np.ndarray) -> np.ndarray:
        free = self.map.free & passable
        unknown = ~self.map.explored()
        frontier: np.ndarray = free & ndimage.binary_dilation(unknown, structure=_CROSS)
        # unknown cells right next to the path stay unknown (the camera cannot see the floor at
        # its feet, nor surfaces nearer than 0.5 m): going there again would show nothing new
        frontier &= ~self._given_up & ~self._around_path
        labels, count = ndimage.label(frontier, structure=np.ones((3, 3), dtype=bool))
        if count == 0:
            return frontier
        sizes = np.bincount(labels.ravel())
        sizes[0] = 0
        large: np.ndarray = sizes[labels] >= self.settings.min_frontier_cells
        return large

    def _step(self, position: np.ndarray, heading: float) -> int:
        assert self._field is not None
        self._since_plan += 1
        action = reference_choose_action(
            self.grid, self._field, self._passable, position, heading, self.motion
        )
        if action is None:
            # a local minimum of the field (map changed under the plan): re-plan, look around
            self._stuck += 1
            self._field = None
            if self._stuck > 3:
                self._stuck = 0
                if self._tight == 0:
                    # the plan runs through a gap the margin left one cell wide, which 0.25 m
                    # steps at 30° headings cannot enter: drop the margin for a while
                    self._squeeze()
                elif self._target == ("frontier", -1):
                    self._give_up_near(position)
                else:  # cannot get nearer to the goal: aim at a wider ring
                    self._aim = min(self._aim + 1, len(GOAL_RADII) - 1)
            return int(Action.TURN_LEFT if self.rng.random() < 0.5 else Action.TURN_RIGHT)
        self._stuck = 0
        return action

    def _give_up_near(self, position: np.ndarray) -> None:
        """Stop aiming at frontier cells around a spot the agent keeps failing to reach."""
        self._given_up |= self._disc(position, 1.0)
        self._stuck = 0

    def _straight_and_free(self, start: np.ndarray, end: np.ndarray) -> bool:
        """Every cell on the segment is seen free floor, up to the goal's own cell."""
        free = (self.map.free | self._visited) & ~self.map.obstacle
        return bool(self.grid.lookup(free, self._segment(start, end), outside=False).all())

    def _disc(self, centre: np.ndarray, radius: float) -> np.ndarray:
        mask = np.zeros((self.settings.map_size, self.settings.map_size), dtype=bool)
        cells = int(math.ceil(radius / self.settings.cell_size))
        row, col = (int(v) for v in self.grid.to_cell(centre))
        r0, r1 = max(0, row - cells), min(self.settings.map_size, row + cells + 1)
        c0, c1 = max(0, col - cells), min(self.settings.map_size, col + cells + 1)
        rr, cc = np.mgrid[r0:r1, c0:c1]
        mask[r0:r1, c0:c1] = np.hypot(rr - row, cc - col) * self.settings.cell_size <= radius
        return mask
