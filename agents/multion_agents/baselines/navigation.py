"""Grid planning shared by the planner baselines: a map frame, distance fields, and a step chooser.

Both planners keep a square top-down grid in the *start frame*, the frame of the GPS sensor
(x ahead, y left of the start pose). The grid is laid out like the oracle map's egocentric crop
at the first step: row 0 is furthest ahead, column 0 furthest left, the start in the centre
cell. So the oracle map seen at the start *is* a map in this frame, without any resampling.

Planning is fast marching (scikit-fmm) from the goal cells over the free cells, done once per
goal and again only when the agent bumps into something the map did not show. Each step the
agent then looks at the 12 headings it can reach by turning and picks the one whose forward step
lowers the distance field most, so the actual motion (0.25 m steps, 30° turns) needs no separate
path-following controller.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import skfmm
from scipy import ndimage

from multion_client.constants import Action


@dataclass(frozen=True)
class StartFrameGrid:
    """A ``size`` × ``size`` grid of ``cell_size`` metres centred on the start pose."""

    size: int
    cell_size: float

    @property
    def half(self) -> int:
        return self.size // 2

    def to_cell(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Integer ``(rows, cols)`` of start-frame points ``xy`` (..., 2); may be out of range."""
        xy = np.asarray(xy, dtype=np.float64)
        rows = np.rint(self.half - xy[..., 0] / self.cell_size).astype(np.int64)
        cols = np.rint(self.half - xy[..., 1] / self.cell_size).astype(np.int64)
        return rows, cols

    def to_xy(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Start-frame ``(x, y)`` of cell centres."""
        x = (self.half - np.asarray(rows, dtype=np.float64)) * self.cell_size
        y = (self.half - np.asarray(cols, dtype=np.float64)) * self.cell_size
        return np.stack([x, y], axis=-1)

    def lookup(self, values: np.ndarray, xy: np.ndarray, outside: float | bool) -> np.ndarray:
        """``values`` at start-frame points ``xy``; ``outside`` for points off the grid."""
        rows, cols = self.to_cell(xy)
        ok = (rows >= 0) & (rows < self.size) & (cols >= 0) & (cols < self.size)
        out = np.full(rows.shape, outside, dtype=values.dtype)
        out[ok] = values[rows[ok], cols[ok]]
        return out


def interpolate(grid: StartFrameGrid, field: np.ndarray, xy: np.ndarray) -> float:
    """Bilinear value of ``field`` at one start-frame point (``inf`` if a corner is ``inf``).

    Nearest-cell lookups make a point on a cell border flip between two values with float
    rounding, which can make the step chooser swing between two headings forever.
    """
    row = grid.half - float(xy[0]) / grid.cell_size
    col = grid.half - float(xy[1]) / grid.cell_size
    r0, c0 = math.floor(row), math.floor(col)
    if not (0 <= r0 < grid.size - 1 and 0 <= c0 < grid.size - 1):
        return math.inf
    corners = field[r0 : r0 + 2, c0 : c0 + 2]
    if not np.isfinite(corners).all():
        return float(grid.lookup(field, xy, outside=np.inf))
    fr, fc = row - r0, col - c0
    top = corners[0, 0] * (1 - fc) + corners[0, 1] * fc
    bottom = corners[1, 0] * (1 - fc) + corners[1, 1] * fc
    return float(top * (1 - fr) + bottom * fr)


def interpolate_many(grid: StartFrameGrid, field: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """:func:`interpolate` at each of the points ``xy`` (n, 2): the same numbers, at once."""
    row = grid.half - xy[:, 0] / grid.cell_size
    col = grid.half - xy[:, 1] / grid.cell_size
    r0, c0 = np.floor(row).astype(np.int64), np.floor(col).astype(np.int64)
    out = np.full(len(xy), np.inf)
    inside = np.flatnonzero((r0 >= 0) & (r0 < grid.size - 1) & (c0 >= 0) & (c0 < grid.size - 1))
    r, c = r0[inside], c0[inside]
    corners = np.stack([field[r, c], field[r, c + 1], field[r + 1, c], field[r + 1, c + 1]])
    finite = np.isfinite(corners).all(axis=0)
    # a corner at inf: the nearest cell's value, as interpolate does
    out[inside[~finite]] = grid.lookup(field, xy[inside[~finite]], outside=np.inf)
    c00, c01, c10, c11 = corners[:, finite]
    fr, fc = row[inside[finite]] - r[finite], col[inside[finite]] - c[finite]
    top = c00 * (1 - fc) + c01 * fc
    bottom = c10 * (1 - fc) + c11 * fc
    out[inside[finite]] = top * (1 - fr) + bottom * fr
    return out


def distance_field(
    free: np.ndarray,
    sources: np.ndarray,
    cell_size: float,
    wall_margin: float = 0.0,
    slowest: float = 0.5,
    crawl: np.ndarray | None = None,
) -> np.ndarray:
    """Travel distance (metres) from every free cell to the nearest source cell; ``inf`` elsewhere.

    With ``wall_margin`` > 0, cells closer than that to a non-free cell are slower to cross (down
    to ``slowest`` of full speed right next to it), so paths keep off walls where there is room (a
    path that hugs a wall collides when the map is a little off) but still squeeze through narrow
    doors. The result is then a travel time, never less than the plain distance. ``crawl``
    cells are crossed at a tenth of full speed: passable, but only if nothing else is.
    """
    sources = sources & free
    if not sources.any():
        return np.full(free.shape, np.inf)
    phi = np.where(sources, -1.0, 1.0)
    masked = np.ma.MaskedArray(phi, mask=~free)
    try:
        if wall_margin > 0 or crawl is not None:
            speed = np.ones(free.shape)
            if wall_margin > 0:
                clearance = ndimage.distance_transform_edt(free) * cell_size
                speed = np.clip(slowest + (1 - slowest) * clearance / wall_margin, slowest, 1.0)
            if crawl is not None:
                speed[crawl] = 0.1
            field = skfmm.travel_time(masked, speed, dx=cell_size)
        else:
            field = skfmm.distance(masked, dx=cell_size)
    except ValueError:  # no source touches a free non-source cell: nothing to march into
        field = np.ma.MaskedArray(np.where(sources, 0.0, np.inf), mask=~free)
    out = np.asarray(np.ma.filled(field, np.inf), dtype=np.float64)
    out = np.where(out < 0, 0.0, out)
    out[sources] = 0.0
    out[~free] = np.inf
    return out


def cropped_distance_field(
    free: np.ndarray,
    sources: np.ndarray,
    cell_size: float,
    box: tuple[int, int, int, int],
    wall_margin: float = 0.0,
    slowest: float = 0.5,
) -> np.ndarray:
    """:func:`distance_field` computed only inside ``box`` = (row0, row1, col0, col1), ``inf``
    outside: fast marching costs grow with the area, and most of a large map is empty."""
    r0, r1, c0, c1 = box
    out = np.full(free.shape, np.inf)
    out[r0:r1, c0:c1] = distance_field(
        free[r0:r1, c0:c1], sources[r0:r1, c0:c1], cell_size, wall_margin, slowest
    )
    return out


def bounding_box(mask: np.ndarray, margin: int) -> tuple[int, int, int, int]:
    """The smallest box (row0, row1, col0, col1) around ``mask``, grown by ``margin`` cells."""
    rows, cols = np.nonzero(mask)
    if len(rows) == 0:
        return 0, mask.shape[0], 0, mask.shape[1]
    return (
        max(0, int(rows.min()) - margin),
        min(mask.shape[0], int(rows.max()) + margin + 1),
        max(0, int(cols.min()) - margin),
        min(mask.shape[1], int(cols.max()) + margin + 1),
    )


def nearest_free(free: np.ndarray, sources: np.ndarray, radius_cells: int) -> np.ndarray:
    """``sources`` grown by up to ``radius_cells`` and kept on free cells: where to aim when the
    target itself stands on a cell the map marks as blocked (a goal next to a wall)."""
    if (sources & free).any() or radius_cells <= 0:
        on_free: np.ndarray = sources & free
        return on_free
    grown_on_free: np.ndarray = ndimage.binary_dilation(sources, iterations=radius_cells) & free
    return grown_on_free


@dataclass(frozen=True)
class Motion:
    """The agent's action magnitudes (paper §3; the ``agent`` config section, see
    :meth:`from_config`)."""

    forward_step: float = 0.25
    turn_angle: float = math.radians(30.0)

    @classmethod
    def from_config(cls, agent: Mapping[str, Any]) -> Motion:
        """From the ``agent`` section of a resolved environment config (nested dicts); a
        ValueError when the turn angle does not divide a full turn (the planners snap headings
        to whole turns from the start)."""
        degrees = float(agent["turn_angle_deg"])
        turns = round(360.0 / degrees)
        if abs(turns * degrees - 360.0) > 1e-6:
            raise ValueError(
                f"agent.turn_angle_deg={degrees:g} does not divide 360°: the planner snaps "
                "headings to whole turns from the start"
            )
        return cls(float(agent["forward_step"]), math.radians(degrees))

    @property
    def headings(self) -> int:
        return round(2 * math.pi / self.turn_angle)


def snap_heading(heading: float, motion: Motion = Motion()) -> tuple[float, int | None]:
    """``(angle, index)``: a heading that is a whole number of turns from the start, snapped to
    ``index * turn_angle`` (index in 0..n-1); other headings are returned as they are.

    Snapping makes one direction give the very same points whichever heading it is computed
    from; otherwise a point on a cell border can be passable from one side only, and the agent
    swings between two headings forever.
    """
    index = round(heading / motion.turn_angle)
    if abs(heading - index * motion.turn_angle) < 1e-3:
        index %= motion.headings
        return index * motion.turn_angle, index
    return heading, None


def step_points(position: np.ndarray, angle: float, motion: Motion = Motion()) -> np.ndarray:
    """Five points along the forward step from ``position`` in direction ``angle``; the last is
    where the step ends."""
    step = motion.forward_step * np.array([math.cos(angle), math.sin(angle)])
    return position[None, :] + np.linspace(0.0, 1.0, 6)[1:, None] * step[None, :]


def choose_action(
    grid: StartFrameGrid,
    field: np.ndarray,
    passable: np.ndarray,
    position: np.ndarray,
    heading: float,
    motion: Motion = Motion(),
    turn_cost: float = 0.02,
    refused: Collection[int] = (),
) -> int | None:
    """The turn or forward step that starts the best one-step move down ``field``.

    Each reachable heading is scored by the field at the end of a forward step in that direction
    (only if the whole step stays on ``passable`` cells), plus ``turn_cost`` metres per turn
    needed, so the agent does not spin for a centimetre. Returns None when no step goes downhill.
    ``refused``: indices (see :func:`snap_heading`) of headings whose step the simulator refused
    from this very position, which it would refuse again whatever the map says.
    """
    here = interpolate(grid, field, position)
    n = motion.headings
    angle, index = snap_heading(heading, motion)
    best_value, best_turns = here - 1e-6, None
    turns = _turn_order(n)
    # the points of all n steps at once, each exactly as step_points computes it
    if index is None:
        offsets = _step_offsets([_turned(angle, index, t, motion) for t in turns], motion)
    else:  # a snapped heading: the same n steps every time
        offsets = _snapped_step_offsets(motion, index)
    points = position[None, None, :] + offsets
    clear = np.flatnonzero(grid.lookup(passable, points, outside=False).all(axis=1))
    if refused and index is not None:
        clear = np.array([k for k in clear if (index + turns[k]) % n not in refused], dtype=int)
    values = interpolate_many(grid, field, points[clear, -1])
    values += turn_cost * np.abs(np.asarray(turns)[clear])
    for k, value in zip(clear.tolist(), values.tolist(), strict=True):
        if value < best_value:
            best_value, best_turns = value, turns[k]
    return _starting(best_turns)


_STEP_FRACTIONS = np.linspace(0.0, 1.0, 6)[1:]


@functools.cache
def _turn_order(n: int) -> list[int]:
    """Turns (positive: left) in the order :func:`choose_action` tries them."""
    return [k if k <= n // 2 else k - n for k in range(n)]


def _step_offsets(angles: list[float], motion: Motion) -> np.ndarray:
    """What :func:`step_points` adds to the position, for several directions: (n, 5, 2)."""
    unit = np.array([[math.cos(a), math.sin(a)] for a in angles])
    step = motion.forward_step * unit
    return _STEP_FRACTIONS[None, :, None] * step[:, None, :]


@functools.cache
def _snapped_step_offsets(motion: Motion, index: int) -> np.ndarray:
    turns = _turn_order(motion.headings)
    offsets = _step_offsets([_turned(0.0, index, t, motion) for t in turns], motion)
    offsets.flags.writeable = False
    return offsets


def _starting(turns: int | None) -> int | None:
    """The action that starts a move after ``turns`` turns left (negative: right), or None."""
    if turns is None:
        return None
    if turns == 0:
        return int(Action.MOVE_FORWARD)
    return int(Action.TURN_LEFT if turns > 0 else Action.TURN_RIGHT)


def _turned(angle: float, index: int | None, turns: int, motion: Motion) -> float:
    """The heading ``turns`` turns left of a heading snapped by :func:`snap_heading`."""
    if index is not None:
        return ((index + turns) % motion.headings) * motion.turn_angle
    return angle + turns * motion.turn_angle


def two_step_action(
    grid: StartFrameGrid,
    field: np.ndarray,
    passable: np.ndarray,
    position: np.ndarray,
    heading: float,
    motion: Motion = Motion(),
    turn_cost: float = 0.02,
) -> int | None:
    """The first action of the best pair of forward steps (each after any turn) that ends below
    the field here, when :func:`choose_action` finds no single step downhill.

    A passage one map cell wide and not along one of the 12 headings cannot be entered with one
    0.25 m step from where the agent stands, but often with two at different headings; once the
    first is taken, the second is a single downhill step. None if no pair goes downhill."""
    here = interpolate(grid, field, position)
    n = motion.headings
    angle, index = snap_heading(heading, motion)
    best_value, best_first = here - 1e-6, None
    for first in range(-(n // 2) + 1, n // 2 + 1):
        steps_one = step_points(position, _turned(angle, index, first, motion), motion)
        if not grid.lookup(passable, steps_one, outside=False).all():
            continue
        middle = steps_one[-1]
        for second in range(-(n // 2) + 1, n // 2 + 1):
            steps_two = step_points(middle, _turned(angle, index, second, motion), motion)
            if not grid.lookup(passable, steps_two, outside=False).all():
                continue
            between = (second - first) % n
            cost = turn_cost * (abs(first) + min(between, n - between))
            value = interpolate(grid, field, steps_two[-1]) + cost
            if value < best_value:
                best_value, best_first = value, first
    return _starting(best_first)


def steps_ahead(
    grid: StartFrameGrid,
    field: np.ndarray,
    passable: np.ndarray,
    position: np.ndarray,
    heading: float,
    depth: int,
    motion: Motion = Motion(),
    turn_cost: float = 0.02,
    refused: Collection[int] = (),
) -> list[int] | None:
    """The headings (indices, see :func:`snap_heading`) of the best ``depth`` forward steps in
    a row that end below the field here, each on ``passable`` cells all along; None if none
    does, or if ``heading`` is not snapped.

    :func:`two_step_action` for any depth, all sequences at once, and the whole sequence rather
    than its first action: a way into a corridor whose lanes lie between the points one or two
    0.25 m steps at 30° headings reach can take three steps, and only the whole sequence shows
    it goes downhill. ``refused`` as in :func:`choose_action`, for the first step.
    """
    _, index = snap_heading(heading, motion)
    if index is None:
        return None
    n = motion.headings
    offsets = _snapped_step_offsets(motion, 0)  # row k: heading index k (its turn order)
    sequences = _sequences(n, depth)
    ok = ~np.isin(sequences[:, 0], list(refused))
    ends = np.broadcast_to(position, (len(sequences), 2))
    for j in range(depth):
        points = ends[:, None, :] + offsets[sequences[:, j]]
        ok &= grid.lookup(passable, points, outside=False).all(axis=1)
        ends = points[:, -1]
    chosen = np.flatnonzero(ok)
    if len(chosen) == 0:
        return None
    values = interpolate_many(grid, field, ends[chosen])
    headings = np.concatenate([np.full((len(chosen), 1), index), sequences[chosen]], axis=1)
    turns = np.diff(headings, axis=1) % n
    values += turn_cost * np.minimum(turns, n - turns).sum(axis=1)
    best = int(np.argmin(values))
    if values[best] >= interpolate(grid, field, position) - 1e-6:
        return None
    turns_taken: list[int] = sequences[chosen[best]].tolist()
    return turns_taken


@functools.cache
def _sequences(n: int, depth: int) -> np.ndarray:
    """Every sequence of ``depth`` heading indices out of ``n``: (n ** depth, depth)."""
    grids = np.meshgrid(*[np.arange(n)] * depth, indexing="ij")
    sequences = np.stack([g.ravel() for g in grids], axis=1)
    sequences.flags.writeable = False
    return sequences


def cells_ahead(
    grid: StartFrameGrid, position: np.ndarray, heading: float, motion: Motion = Motion()
) -> tuple[np.ndarray, np.ndarray]:
    """The cell a refused forward step would have ended in (empty if it is the agent's own).

    Computed exactly as :func:`choose_action` computes the step, so the marked cell is the one
    it checks. Only the end: marking cells nearer the agent as well can wall it in after a few
    refusals in different directions, and a step that crosses the true obstacle elsewhere is
    refused (and marked) in turn.
    """
    angle, _ = snap_heading(heading, motion)
    rows, cols = grid.to_cell(step_points(position, angle, motion)[-1:])
    here_row, here_col = grid.to_cell(position)
    ok = (rows >= 0) & (rows < grid.size) & (cols >= 0) & (cols < grid.size)
    ok &= (rows != here_row) | (cols != here_col)
    return rows[ok], cols[ok]
