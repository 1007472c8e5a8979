"""Train episodes drawn from a fixed set of goal sites per house (issue 44).

Online sampling (:func:`multion.task.sampling.sample_episode`) marches ``m + 1`` distance fields
per episode: the start's and each goal's. Here each train house has a seeded set of goal sites
(:func:`choose_sites`: one in every room, the rest spread over the floor), and every goal of an
episode is a site. A site's distance field (made with the goal's footprint, as the env makes it)
is marched the first time a goal is drawn there and kept (:class:`SiteFieldCache`, one per
process and shared by its envs, within one byte budget), so once a house's sites are cached a
reset marches nothing, in whichever env of the process marched them.

Goals are drawn backwards (:func:`sample_site_episode`): the last goal among the sites, each
earlier one among the sites whose geodesic to the next goal (read in that goal's field) obeys
the leg's constraints, and the start among the navigable cells within the constraints of the
first goal's field. The constraints are the online sampler's: every leg 2-20 m (or
``online_max_geodesic``), goals ``min_goal_separation`` apart, a start that can step, every goal
reached by the agent's own steps, distractors as before.
"""

from __future__ import annotations

import functools
import hashlib
import threading
import weakref
import zlib
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from multion.config.episode import Episode, Goal
from multion.config.task import EpisodeConstraints
from multion.scenes.layout import Room
from multion.scenes.registry import is_mesh_scene, layout_for
from multion.sim.geodesic import FieldCache, distance_field
from multion.sim.navgrid import NavGrid
from multion.task.sampling import finish_episode
from multion_client.constants import NUM_CATEGORIES

SITES_SEED = 44
"""Seeds every house's sites together with its scene id: the sites of a house never depend on
the env's seed, the order houses are visited in, or how many sites are asked for (the first
``k`` of ``n > k`` sites are the ``k`` sites)."""
SPREAD_CANDIDATES = 16
"""Each site after the rooms' is the farthest from the sites so far of this many random
navigable cells (Mitchell's best candidate): spread out, yet random."""


def house_rooms(scene_id: str) -> tuple[Room, ...]:
    """The rooms of a procedural scene (none for a mesh scan)."""
    if is_mesh_scene(scene_id):
        return ()
    return layout_for(scene_id).rooms


def room_of(rooms: Sequence[Room], xy: np.ndarray) -> np.ndarray:
    """The index of the room holding each point of ``xy`` (shape ``(n, 2)``); -1 outside every
    room (a door's gap between two rooms' interiors)."""
    points = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    index = np.full(len(points), -1, dtype=np.int64)
    for number, room in enumerate(rooms):
        x0, y0, x1, y1 = room.rect
        inside = (
            (points[:, 0] >= x0)
            & (points[:, 0] <= x1)
            & (points[:, 1] >= y0)
            & (points[:, 1] <= y1)
        )
        index[(index < 0) & inside] = number
    return index


def choose_sites(grid: NavGrid, rooms: Sequence[Room], count: int, scene_id: str) -> np.ndarray:
    """``count`` goal sites of a house: indices into its navigable cells (the order of
    ``np.nonzero(grid.navigable)``). First one random cell in every room that has navigable
    cells (the rooms in a seeded order, so with fewer sites than rooms the rooms kept are
    random), then sites spread over the whole floor. Seeded by ``scene_id`` alone."""
    rng = np.random.default_rng([SITES_SEED, zlib.crc32(scene_id.encode("utf-8"))])
    rows, cols = np.nonzero(grid.navigable)
    cells = grid.cell_to_world(rows, cols)
    if len(cells) < count:
        raise ValueError(
            f"{scene_id} has {len(cells)} navigable cells, fewer than the {count} goal sites asked"
        )
    in_room = room_of(rooms, cells)
    chosen: list[int] = []
    for number in rng.permutation(len(rooms)):
        members = np.flatnonzero(in_room == number)
        if len(members) and len(chosen) < count:
            chosen.append(int(members[rng.integers(len(members))]))
    nearest = np.full(len(cells), np.inf)
    for site in chosen:
        nearest = np.minimum(nearest, np.hypot(*(cells - cells[site]).T))
    if not chosen:  # no rooms: the first site anywhere
        chosen.append(int(rng.integers(len(cells))))
        nearest = np.hypot(*(cells - cells[chosen[0]]).T)
    while len(chosen) < count:
        candidates = rng.integers(len(cells), size=SPREAD_CANDIDATES)
        site = int(candidates[np.argmax(nearest[candidates])])
        if nearest[site] == 0.0:  # every candidate is a site already: take any other cell
            site = int(np.flatnonzero(nearest > 0)[0])
        chosen.append(site)
        nearest = np.minimum(nearest, np.hypot(*(cells - cells[site]).T))
    return np.asarray(chosen, dtype=np.int64)


@dataclass
class HouseSites:
    """One house's grid, navigable cells and goal sites (about 0.5 MB a house: the cells are
    kept as int32 rows and columns, their world points made when needed)."""

    scene_id: str
    grid: NavGrid
    grid_key: bytes
    """A digest of the grid (:func:`grid_digest`): what, with the scene id, decides the sites."""
    rows: np.ndarray
    """Rows of the navigable cells, in ``np.nonzero`` order (int32)."""
    cols: np.ndarray
    sites: np.ndarray
    """Indices of the sites into the navigable cells."""
    site_xy: np.ndarray
    """The sites' world ``(x, y)``, rounded as an episode stores a goal's position."""

    def full_field(self, values: np.ndarray) -> np.ndarray:
        """A field over the whole grid from its values on the navigable cells (``inf``
        elsewhere, as :func:`distance_field` makes it)."""
        field = np.full(self.grid.shape, np.inf)
        field[self.rows, self.cols] = values
        field.flags.writeable = False
        return field

    def cells(self, indices: np.ndarray | None = None) -> np.ndarray:
        """World ``(x, y)`` of the navigable cells' centres (those of ``indices``, or all)."""
        if indices is None:
            return self.grid.cell_to_world(self.rows, self.cols)
        return self.grid.cell_to_world(self.rows[indices], self.cols[indices])


def grid_digest(grid: NavGrid) -> bytes:
    """What of a grid decides a house's sites and a site's field: its origin, cell size and
    navigable cells (0.1 ms for a train house's grid)."""
    digest = hashlib.blake2b(digest_size=16)
    digest.update(repr((grid.origin, grid.cell_size, grid.shape)).encode("ascii"))
    digest.update(np.ascontiguousarray(grid.navigable).tobytes())
    return digest.digest()


FieldKey = tuple[str, bytes, float, float, float]
"""A site field's key: scene id, grid digest, the site's rounded ``(x, y)``, goal radius."""


class SiteFieldCache:
    """The goal sites of the houses visited in one process and their distance fields, shared by
    every :class:`GoalSites` (one per env) of the process.

    A field is kept as its values on the navigable cells (float64, 8 bytes a cell: 0.5 MB in a
    median train house), keyed by what decides it (:data:`FieldKey`), so an env reads the
    fields another env marched. The least recently used fields are dropped to keep them within
    ``budget_bytes``: the largest budget of the users present (each env's
    ``task.goal_site_cache_mib``), so one process holds one budget whatever its env count. When
    the last user leaves, every field and house is dropped (a server worker whose sessions
    drawing from sites are closed gives their memory back). Thread-safe.
    """

    def __init__(self) -> None:
        self.held_bytes = 0
        self.marched = 0
        """Fields marched so far (a cache miss each), by every user."""
        self._budgets: dict[int, int] = {}
        self._next_user = 0
        self._houses: dict[tuple[str, bytes, int], HouseSites] = {}
        self._fields: OrderedDict[FieldKey, np.ndarray] = OrderedDict()
        self._lock = threading.RLock()

    @property
    def budget_bytes(self) -> int:
        """The largest budget of the users present (0 with none)."""
        return max(self._budgets.values(), default=0)

    @property
    def users(self) -> int:
        return len(self._budgets)

    @property
    def fields_held(self) -> int:
        return len(self._fields)

    def join(self, budget_bytes: int) -> int:
        """Count a new user asking for ``budget_bytes``; returns its ticket for :meth:`leave`."""
        if budget_bytes < 1:
            raise ValueError(f"budget_bytes must be at least 1, got {budget_bytes}")
        with self._lock:
            self._next_user += 1
            self._budgets[self._next_user] = budget_bytes
            return self._next_user

    def leave(self, ticket: int) -> None:
        """A user is gone: the budget shrinks to the largest left, or everything is dropped."""
        with self._lock:
            if self._budgets.pop(ticket, None) is None:
                return
            if not self._budgets:
                self._fields.clear()
                self._houses.clear()
                self.held_bytes = 0
            else:
                self._shrink()

    def house(self, scene_id: str, grid: NavGrid, count: int) -> HouseSites:
        """The ``count`` sites of ``scene_id`` on ``grid``, chosen on the first visit."""
        key = (scene_id, grid_digest(grid), count)
        with self._lock:
            house = self._houses.get(key)
            if house is None:
                rows, cols = (index.astype(np.int32) for index in np.nonzero(grid.navigable))
                sites = choose_sites(grid, house_rooms(scene_id), count, scene_id)
                site_xy = np.round(grid.cell_to_world(rows[sites], cols[sites]), 4)
                house = HouseSites(scene_id, grid, key[1], rows, cols, sites, site_xy)
                self._houses[key] = house
            return house

    def values(self, house: HouseSites, site: int, goal_radius: float) -> tuple[np.ndarray, bool]:
        """Site ``site``'s distance field on the house's navigable cells (``np.nonzero``
        order), and whether it was marched now (a miss)."""
        x, y = (float(v) for v in house.site_xy[site])
        key = (house.scene_id, house.grid_key, x, y, float(goal_radius))
        with self._lock:
            values = self._fields.get(key)
            if values is not None:
                self._fields.move_to_end(key)
                return values, False
            field = distance_field(house.grid, house.site_xy[site], goal_radius)
            self.marched += 1
            values = field[house.rows, house.cols]
            values.flags.writeable = False
            self._fields[key] = values
            self.held_bytes += values.nbytes
            self._shrink()
            return values, True

    def _shrink(self) -> None:
        # the newest field stays even above the budget: the caller is about to read it
        while self.held_bytes > self.budget_bytes and len(self._fields) > 1:
            _, dropped = self._fields.popitem(last=False)
            self.held_bytes -= dropped.nbytes


PROCESS_SITE_CACHE = SiteFieldCache()
"""The one cache of this process: every env's :class:`GoalSites` uses it."""


class GoalSites:
    """One env's view of the goal sites: ``count`` sites a house, fields for goals of
    ``goal_radius``, read from ``cache`` (the process's, :data:`PROCESS_SITE_CACHE`, unless
    one is given), which this view asks to hold ``budget_bytes``. :meth:`close` (or the view's
    garbage collection) withdraws the request."""

    def __init__(
        self,
        count: int,
        goal_radius: float,
        budget_bytes: int,
        cache: SiteFieldCache = PROCESS_SITE_CACHE,
    ) -> None:
        self.count = count
        self.goal_radius = goal_radius
        self.cache = cache
        self.marched = 0
        """Fields this view marched (its cache misses)."""
        self._last: HouseSites | None = None
        self._last_grid: NavGrid | None = None
        self._ticket = cache.join(budget_bytes)
        self._leave = weakref.finalize(self, cache.leave, self._ticket)

    def close(self) -> None:
        self._leave()

    @property
    def budget_bytes(self) -> int:
        """The shared cache's budget (the largest its users ask for)."""
        return self.cache.budget_bytes

    @property
    def held_bytes(self) -> int:
        return self.cache.held_bytes

    @property
    def fields_held(self) -> int:
        return self.cache.fields_held

    def house(self, scene_id: str, grid: NavGrid) -> HouseSites:
        """The sites of ``scene_id``, chosen on the first visit in this process. A grid built
        again for the same scene (the simulator keeps only some in memory) keeps them when its
        cells are the same."""
        last = self._last
        if last is not None and last.scene_id == scene_id and self._last_grid is grid:
            return last  # the usual case, episodes in one house: no digest
        self._last = self.cache.house(scene_id, grid, self.count)
        self._last_grid = grid
        return self._last

    def values(self, house: HouseSites, site: int) -> np.ndarray:
        """Site ``site``'s distance field on the house's navigable cells (``np.nonzero``
        order): the geodesic from each cell to the goal's footprint, as the env measures it."""
        values, marched = self.cache.values(house, site, self.goal_radius)
        self.marched += marched
        return values


def sample_site_episode(
    sites: GoalSites,
    grid: NavGrid,
    scene_id: str,
    num_goals: int,
    rng: np.random.Generator,
    episode_id: str,
    constraints: EpisodeConstraints = EpisodeConstraints(),
    num_distractors: int = 0,
    fields: FieldCache | None = None,
) -> Episode | None:
    """Sample one episode whose goals are goal sites, or None when ``max_tries`` draws fail.

    The same guarantees as :func:`multion.task.sampling.sample_episode`: every leg's geodesic
    (start to goal 1, goal i to goal i + 1, each read in the goal's field as the env reads it)
    in ``[min_geodesic, max_geodesic]``, goals ``min_goal_separation`` apart, categories without
    replacement, distractors away from the goals, a start that can step, every goal reached by
    the agent's steps. ``fields``, when given, receives the goals' full fields for the reset.
    """
    if not 0 <= num_distractors <= NUM_CATEGORIES - num_goals:
        raise ValueError(
            f"num_distractors must be in 0..{NUM_CATEGORIES - num_goals} for {num_goals} goals, "
            f"got {num_distractors}"
        )
    house = sites.house(scene_id, grid)
    low, high = constraints.min_geodesic, constraints.max_geodesic
    z = grid.floor_z
    for _ in range(constraints.max_tries):
        backwards = [int(rng.integers(len(house.sites)))]  # the last goal first
        for _earlier in range(num_goals - 1):
            to_next = sites.values(house, backwards[-1])[house.sites]
            ok = (to_next >= low) & (to_next <= high)
            for later in backwards:
                gap = np.hypot(*(house.site_xy - house.site_xy[later]).T)
                ok &= gap >= constraints.min_goal_separation
            candidates = np.flatnonzero(ok)
            if len(candidates) == 0:
                break
            backwards.append(int(candidates[rng.integers(len(candidates))]))
        if len(backwards) != num_goals:
            continue
        order = backwards[::-1]
        to_first = sites.values(house, order[0])
        candidates = np.flatnonzero((to_first >= low) & (to_first <= high))
        if len(candidates) == 0:
            continue
        start_cell = int(candidates[rng.integers(len(candidates))])
        measured = [float(to_first[start_cell])] + [
            float(sites.values(house, goal)[house.sites[before]])
            for before, goal in zip(order, order[1:], strict=False)
        ]
        categories = rng.choice(NUM_CATEGORIES, size=num_goals, replace=False)
        goals = tuple(
            Goal(
                category=int(c),
                position=(float(house.site_xy[s][0]), float(house.site_xy[s][1]), z),
            )
            for c, s in zip(categories, order, strict=True)
        )
        start = house.cells(np.array([start_cell]))[0]
        goal_fields = functools.cache(  # made once: for the steps' check, then the env's cache
            lambda order=order: [house.full_field(sites.values(house, s)) for s in order]
        )
        episode = finish_episode(
            rng, grid, episode_id, scene_id, start, goals, measured, goal_fields, constraints,
            num_distractors, house.cells,
        )  # fmt: skip
        if episode is None:
            continue
        if fields is not None:
            for site, field in zip(order, goal_fields(), strict=True):
                fields.put(grid, house.site_xy[site], sites.goal_radius, field)
        return episode
    return None
