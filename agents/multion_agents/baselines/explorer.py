"""``explorer``: frontier exploration with a map built from depth, goals recognised by colour.

No oracle: the agent reads RGB, depth, GPS, compass and the current goal category. It keeps a
top-down map in the start frame (:class:`~.mapping.SemanticMap`): obstacles and free space from
depth, and the position of *every* goal colour it has seen, not only the current one. That memory
is the paper's point about maps: when a goal becomes current, the agent often already knows where
it is and walks straight there instead of exploring again.

Policy, per step:

1. at the start of an episode, turn once around on the spot to look;
2. if the current goal has been seen, plan to it; FOUND once within ``found_distance`` along the
   map and in a straight, free line (or in view), which keeps inside the 1.5 m geodesic radius;
3. otherwise go to the nearest frontier (known free cells next to unknown ones).

Escapes (the failures of docs/baselines.md): stuck for two full turns on the way to a
remembered goal, it explores elsewhere for ``detour_steps`` steps (another way in shows up);
arriving a second time where a frontier plan already ended, it gives that spot up (a frontier
round a table that depth never closes); when the margin kept round seen obstacles walls it in,
or leaves the plan's way one cell wide, it plans over the obstacles alone for ``tight_steps``;
when no single step goes down the plan, it looks two, then three steps ahead and follows the steps
found (a corridor whose lanes no single 30° step reaches). The steps refused from where it stands
are never retried before it moves. Arriving at one position a third time for one target, it is
going round in circles: it searches the positions its steps reach, never trying a step twice,
until it is 1 m down the plan (:mod:`.field_steps`, :mod:`.lattice_search`).

A goal colour is a goal only in a blob at most 0.2 m wide (:func:`~.mapping.goal_shaped`): white
paint under bright light renders exactly as the white goal does.

Plans are fast-marching fields (:mod:`.navigation`) over the explored part of the map, refreshed
every ``replan_every`` steps, on arrival, when a step is refused, or when the target changes, so
the agent's thinking stays a small fraction of the simulator's rendering time.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np
from scipy import ndimage

from multion.config.ranges import bounded, check_fields, one_of
from multion_agents.agent import Agent, AgentError, ConfigOverrides, EnvConfigDict, Observation
from multion_agents.baselines.field_steps import FieldSteps
from multion_agents.baselines.grid_discs import GridDiscs, box_grown, box_union
from multion_agents.baselines.mapping import (
    CameraModel,
    DepthProjector,
    SemanticMap,
    detect_goals,
    goal_shaped,
)
from multion_agents.baselines.navigation import (
    Motion,
    StartFrameGrid,
    cells_ahead,
    cropped_distance_field,
    interpolate,
)
from multion_client.constants import Action

_CROSS = ndimage.generate_binary_structure(2, 1)
_EIGHT = np.ones((3, 3), dtype=bool)
GOAL_RADII = (0.2, 0.5, 0.8)
"""How close to a goal the agent aims, in metres: wider when the nearer cells are unreachable in
the map (a goal tucked between furniture), still close enough for FOUND."""


@dataclass
class StepTimes:
    """Seconds spent in each part of :meth:`ExplorerAgent.act`, summed over ``steps`` steps."""

    steps: int = 0
    mapping: float = 0.0  # goal colours, their shape test, depth into the map
    planning: float = 0.0  # passable cells, fast-marching plans, the step chosen
    rest: float = 0.0  # learning from the last action, bookkeeping


@dataclass(frozen=True)
class ExplorerSettings:
    """The explorer's tunables (metres, cells, steps), recorded in ``metrics.json``."""

    cell_size: float = bounded(0.1, 0.01, 1.0)
    map_size: int = bounded(601, 11, 4001)
    """Cells of the square map: 601 is ±30 m around the start, any house fits (up to 25 m)."""
    depth_rays: int = bounded(64, 1, 1024)
    """Depth is sampled on a grid of this many × this many pixels, whatever the resolution."""
    found_distance: float = bounded(1.0, 0.0, 1.5, low_open=True)
    """Map distance to a seen goal that calls FOUND (inside the task's 1.5 m success radius)."""
    replan_every: int = bounded(8, 1, 1000)
    wall_margin: float = bounded(0.35, 0.0, 2.0)
    """Metres kept round seen obstacles when planning."""
    min_frontier_cells: int = bounded(4, 1, 1000)
    close_range: float = bounded(0.6, 0.0, 5.0)
    detour_steps: int = bounded(60, 0, 10_000)
    tight_steps: int = bounded(100, 0, 10_000)
    look_ahead: int = bounded(3, 1, 5)
    """Steps looked ahead when no single one goes down the plan (1: none)."""
    lattice_search: bool = one_of(True, (True, False))
    """Search the step lattice when going round in circles."""

    def __post_init__(self) -> None:
        check_fields(self, "explorer")


class ExplorerAgent(Agent):
    """Frontier exploration + colour goal detection + goal memory, all from RGB-D and pose."""

    sensors: ClassVar[tuple[str, ...]] = ("rgb", "depth", "goal", "gps", "compass")
    config_overrides: ClassVar[ConfigOverrides] = {}
    camera: CameraModel = CameraModel()
    motion: Motion = Motion()

    def __init__(self, seed: int = 0, settings: ExplorerSettings = ExplorerSettings()) -> None:
        super().__init__(seed)
        self.settings = settings
        self.times = StepTimes()  # over the agent's life, for `multion bench --only explorer`
        self.reset()

    def recorded_settings(self) -> dict[str, Any]:
        return asdict(self.settings)

    def configure(self, config: EnvConfigDict) -> None:
        """The camera model and action magnitudes of the environment (``camera``, ``agent``)."""
        super().configure(config)
        goal_set = config.get("task", {}).get("goal_set", "colours")
        if goal_set != "colours":
            raise AgentError(
                f"explorer: it tells goals apart by their colours, and task.goal_set={goal_set!r} "
                "draws goals of one colour; use task.goal_set=colours"
            )
        try:
            motion = Motion.from_config(config["agent"])
        except ValueError as error:
            raise AgentError(f"explorer: {error}") from None
        camera = CameraModel.from_config(config["camera"])
        if camera.far <= camera.near:
            raise AgentError(
                f"explorer: the depth range [{camera.min_depth:g}, {camera.max_depth:g}] m "
                f"(camera.min_depth, camera.max_depth) leaves nothing of the "
                f"[{camera.near_limit:g}, {camera.far_limit:g}] m it maps from"
            )
        self.camera, self.motion = camera, motion
        self.reset()

    def reset(self) -> None:
        self.grid = StartFrameGrid(self.settings.map_size, self.settings.cell_size)
        self.map = SemanticMap(self.grid)
        self.discs = GridDiscs(self.grid)
        self._projector: DepthProjector | None = None
        self._blocked = np.zeros((self.settings.map_size, self.settings.map_size), dtype=bool)
        self._steps = FieldSteps(self.grid, self.motion)  # refused headings, steps planned ahead
        self._given_up = np.zeros_like(self._blocked)
        self._passable = np.ones_like(self._blocked)
        self._visited = np.zeros_like(self._blocked)  # cells the agent's centre has been in
        self._around_path = np.zeros_like(self._blocked)  # cells within reach of the path
        self._field: np.ndarray | None = None
        self._target: tuple[str, int] | None = None  # ("goal", category) or ("frontier", -1)
        self._target_point: np.ndarray | None = None
        self._aim = 0  # index into GOAL_RADII
        self._since_plan = 0
        self._spin = self.motion.headings - 1
        self._stuck = 0
        self._still = 0  # steps since the agent last moved
        self._last_position: np.ndarray | None = None
        self._last_action: int | None = None
        self._detour = 0  # steps left exploring elsewhere after getting stuck on the way to a goal
        self._arrivals: list[np.ndarray] = []  # where frontier plans ended
        self._tight = 0  # steps left planning without the margin round obstacles

    @property
    def searches(self) -> int:
        """Lattice searches started in the episode (going round in circles)."""
        return self._steps.searches

    # ------------------------------------------------------------------ the policy
    def act(self, observation: Observation) -> int:
        start = time.perf_counter()
        position = np.asarray(observation["gps"], dtype=np.float64)
        heading = float(observation["compass"][0])
        goal = int(observation["goal"])
        seen_now = self._perceive(observation, position, heading)
        mapped = time.perf_counter()
        self._track_motion(position, heading)
        if self._tight > 0:
            self._tight -= 1
            self.map.changed |= self._tight == 0  # the margin comes back
        tracked = time.perf_counter()
        if self.map.changed:
            self._refresh_passable()
        action = self._decide(goal, goal in seen_now, position, heading)
        self._last_position, self._last_action = position, action
        end = time.perf_counter()
        times = self.times
        times.steps += 1
        times.mapping += mapped - start
        times.rest += tracked - mapped
        times.planning += end - tracked
        return action

    def took(self, action: int) -> None:
        """The action taken after the last :meth:`act`, when it was not the explorer's own (it
        labels a learner's states: ``learned/expert.py``): what the next step learns from, a
        refused forward step above all, is what was done."""
        self._last_action = int(action)

    def _track_motion(self, position: np.ndarray, heading: float) -> None:
        """Learn from the last action: refused steps, cells stood in, turning without end."""
        moved = self._last_position is None or not _close(position, self._last_position)
        if self._last_action == Action.MOVE_FORWARD and not moved:
            self._blocked[cells_ahead(self.grid, position, heading, self.motion)] = True
            self._steps.refused(heading)
            self._field = None
            self.map.changed = True
        if moved:
            self._steps.moved(position)
        row, col = (int(v) for v in self.grid.to_cell(position))
        if not self._visited[row, col]:
            self._visited[row, col] = True
            self.discs.paint(self._around_path, position, self.settings.close_range, True)
            self.map.changed = True
        self._still = 0 if moved else self._still + 1
        if self._still > 2 * self.motion.headings and self._spin == 0:
            # two full circles without moving: whatever the plan says, it is not working; forget
            # the refusals around here (the simulator will refuse again if it must)
            self._still = 0
            self._field = None
            # the refused steps from this very spot stay refused (``FieldSteps``): retrying
            # them took whole episodes at starts with few free headings
            self.discs.paint(self._blocked, position, 0.5, False)
            self.map.changed = True
            if self._target == ("frontier", -1):
                self._give_up_near(position)
            else:
                # stuck on the way to a remembered goal (pressing against a doorway the map
                # thinks is open): explore elsewhere for a while, which finds another way in
                self._detour = self.settings.detour_steps

    def _decide(self, goal: int, goal_in_view: bool, position: np.ndarray, heading: float) -> int:
        goal_at = self.map.goal_position(goal)
        if self._detour > 0 and not goal_in_view:
            self._detour -= 1
            goal_at = None
        if goal_at is not None:
            self._spin = 0  # somewhere to go: the look around is over
            target = ("goal", goal)
            if self._target != target:
                self._aim, self._field = 0, None
                self._steps.new_target()
            if self._moved(goal_at):
                self._field = None
            self._target, self._target_point = target, goal_at
            if self._field is None:
                self._plan(position)
            if self._close_enough(position, goal_at, goal_in_view):
                return int(Action.FOUND)
        else:
            if self._spin > 0:
                self._spin -= 1
                return int(Action.TURN_LEFT)
            if self._target != ("frontier", -1):
                self._steps.new_target()
            if self._target != ("frontier", -1) or self._needs_frontier_replan(position):
                self._target, self._target_point = ("frontier", -1), None
                self._field = None
            if self._field is None:
                self._plan(position)
        return self._step(position, heading)

    def _step(self, position: np.ndarray, heading: float) -> int:
        assert self._field is not None
        self._since_plan += 1
        # the margin already dropped, yet no single step goes down the plan: look further ahead
        look_ahead = self.settings.look_ahead if self._tight > 0 else 1
        action = self._steps.action(
            self._field, self._passable, position, heading, look_ahead, self.settings.lattice_search
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

    # ------------------------------------------------------------------ perception
    def _perceive(self, observation: Observation, position: np.ndarray, heading: float) -> set[int]:
        depth, rgb = observation["depth"], observation["rgb"]
        if self._projector is None:
            stride = max(1, depth.shape[1] // self.settings.depth_rays)
            self._projector = DepthProjector(depth.shape[:2], self.camera, stride)
        detections = goal_shaped(detect_goals(rgb), depth, self.camera)
        self.map.integrate(self._projector, depth, detections, position, heading)
        self.map.mark_free_disc(position, 0.15)
        return set(detections)

    # ------------------------------------------------------------------ planning
    def _refresh_passable(self) -> None:
        """Passable = not within one cell of a seen obstacle, and not refused by the simulator.

        Optimistic: unknown cells count as passable, since the camera looks where the agent goes.
        The margin round obstacles (kept by the map as they are added) is applied only in the
        box round them, to stay cheap every step.
        """
        # outside the box round the obstacles nothing is inflated: passable = not refused
        r0, r1, c0, c1 = self.map.obstacle_extent.box(2, self.settings.map_size)
        if self._tight > 0:  # walled in by the margin: only the obstacles themselves block
            inflated = self.map.obstacle[r0:r1, c0:c1]
        else:  # one cell round each obstacle
            inflated = self.map.obstacle_grown[r0:r1, c0:c1]
        passable = ~self._blocked
        # where the agent has been is passable, whatever the dilation says
        passable[r0:r1, c0:c1] &= ~inflated | self._visited[r0:r1, c0:c1]
        self._passable = passable

    def _plan(self, position: np.ndarray) -> None:
        # the box round what is known and the discs round the agent and its target
        known = self.map.explored_extent.bounds()
        for centre in (position, self._target_point):
            if centre is not None:
                known = box_union(known, self.discs.box(centre, 1.0))
        box = box_grown(known, 8, self.settings.map_size)
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

    def _squeeze(self) -> None:
        """Plan over the obstacles alone, without the margin round them, for ``tight_steps``
        steps; the simulator refuses what is really too tight."""
        self._tight = self.settings.tight_steps
        self._refresh_passable()

    def _field_to(self, sources: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
        return cropped_distance_field(
            self._passable,
            sources,
            self.settings.cell_size,
            box,
            self.settings.wall_margin,
            slowest=0.3,
        )

    def _frontier(self, passable: np.ndarray) -> np.ndarray:
        # free cells lie in the box round explored ones; one more cell holds their neighbours
        out = np.zeros_like(passable)
        if self.map.explored_extent.empty:
            return out
        r0, r1, c0, c1 = self.map.explored_extent.box(1, self.settings.map_size)
        window = np.s_[r0:r1, c0:c1]
        free = self.map.free[window] & passable[window]
        unknown = ~self.map.explored_within((r0, r1, c0, c1))
        frontier = free & ndimage.binary_dilation(unknown, structure=_CROSS)
        # unknown cells right next to the path stay unknown (the camera cannot see the floor at
        # its feet, nor surfaces nearer than 0.5 m): going there again would show nothing new
        frontier &= ~self._given_up[window] & ~self._around_path[window]
        labels, count = ndimage.label(frontier, structure=_EIGHT)
        if count == 0:
            return out
        sizes = np.bincount(labels.ravel())
        sizes[0] = 0
        out[window] = sizes[labels] >= self.settings.min_frontier_cells
        return out

    def _needs_frontier_replan(self, position: np.ndarray) -> bool:
        if self._field is None or self._since_plan >= self.settings.replan_every:
            return True
        arrived = float(self.grid.lookup(self._field, position, outside=np.inf)) < 0.3
        if arrived:
            # arriving again where an earlier frontier plan ended means that frontier never
            # closes (floor round a table that depth never shows): stop aiming there
            if any(float(np.hypot(*(position - p))) < 1.0 for p in self._arrivals):
                self._give_up_near(position)
            self._arrivals.append(position.copy())
        return arrived

    def _give_up_near(self, position: np.ndarray) -> None:
        """Stop aiming at frontier cells around a spot the agent keeps failing to reach."""
        self.discs.paint(self._given_up, position, 1.0, True)
        self._stuck = 0

    def _moved(self, goal_at: np.ndarray) -> bool:
        return self._target_point is None or float(np.hypot(*(goal_at - self._target_point))) > 0.2

    def _ring(self, centre: np.ndarray, radius: float) -> np.ndarray:
        """Cells within ``radius`` of a goal with a clear line to it: a wider ring must not
        reach round a wall to the far side, where the goal is near but the way to it long."""
        ring = self.discs.disc(centre, radius)
        rows, cols = np.nonzero(ring)
        cells = self.grid.to_xy(rows, cols)
        # from each cell towards the goal, stopping a cell short of the goal's own cell
        gaps = np.hypot(*(cells - centre).T)
        reach = np.clip(1.0 - self.settings.cell_size / np.maximum(gaps, 1e-9), 0.0, 1.0)
        t = np.linspace(0.0, 1.0, int(math.ceil(2 * radius / self.settings.cell_size)) + 2)
        t = t[None, :] * reach[:, None]
        points = cells[:, None, :] + t[:, :, None] * (centre - cells)[:, None, :]
        blocked = self.grid.lookup(self.map.obstacle, points, outside=True).any(axis=1)
        ring[rows[blocked], cols[blocked]] = False
        return ring

    def _close_enough(self, position: np.ndarray, goal_at: np.ndarray, in_view: bool) -> bool:
        assert self._field is not None
        gap = float(np.hypot(*(goal_at - position)))
        if self._stuck > 0 and gap <= self.settings.found_distance + 0.3:
            # cannot get any nearer, but in a straight free line this is still well inside the
            # 1.5 m success radius
            return self._straight_and_free(position, goal_at)
        if gap > self.settings.found_distance:
            return False
        # the field measures the way to the ring aimed at; add its radius for the way to the goal
        along_map = interpolate(self.grid, self._field, position) + GOAL_RADII[self._aim]
        if along_map > self.settings.found_distance + 0.5:
            return False
        if in_view:
            # seen over something low (a bed, a table) is not near: the way round can be long
            return not self.grid.lookup(
                self.map.obstacle, self._segment(position, goal_at), True
            ).any()
        return self._straight_and_free(position, goal_at)

    def _straight_and_free(self, start: np.ndarray, end: np.ndarray) -> bool:
        """Every cell on the segment is seen free floor, up to the goal's own cell."""
        points = self._segment(start, end)
        free = self.grid.lookup(self.map.free, points, outside=False)
        free |= self.grid.lookup(self._visited, points, outside=False)
        free &= ~self.grid.lookup(self.map.obstacle, points, outside=False)
        return bool(free.all())

    def _segment(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """Points from ``start`` towards ``end``, stopping a cell short of ``end``."""
        gap = float(np.hypot(*(end - start)))
        t = np.linspace(0.0, max(0.0, 1.0 - self.settings.cell_size / max(gap, 1e-9)), 12)[:, None]
        points: np.ndarray = (1 - t) * start[None, :] + t * end[None, :]
        return points


def _close(a: np.ndarray, b: np.ndarray) -> bool:
    """``np.allclose(a, b, atol=1e-4)`` for two points, without its overhead per call."""
    return all(
        abs(x - y) <= 1e-4 + 1e-5 * abs(y) for x, y in zip(a.tolist(), b.tolist(), strict=True)
    )
