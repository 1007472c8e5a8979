"""Hidden episodes and houses, generated on the server from the challenge's secret.

Every number here comes from ``HMAC-SHA256(secret, label)``:

* the houses of a (track, phase) are procedural houses ``house-N`` with N ≥ 10⁹ drawn from the
  secret (the packaged splits use houses 0–89), built by the packaged houses' own generator
  (8–16 rooms) unless the challenge narrows the room range (``house-N-rK``). No two (track,
  phase) pairs of a challenge share a house, so an oracle track cannot map a standard track's;
* a **fixed** phase has one set of episodes sampled in its houses, which every run plays in
  its own shuffled order;
* a **fresh** phase draws each run's episodes from the secret and the run's id (episode k of
  run r in a house assigned to k), so no two runs play the same episodes and nothing learned
  in one run can be replayed in the next.

Nothing is written to disk; the same secret always gives the same houses and episodes, so a
stored run can be replayed and re-scored later. Without the secret nothing can be guessed.

This module derives the numbers and loads no simulator (the leaderboard's server process imports
it); building houses and sampling in them happen in :mod:`.hidden_sampling`, reached through
:mod:`.hidden_entry` in the helper process (or a command's own process).
"""

from __future__ import annotations

import functools
import hashlib
import hmac
import logging
import multiprocessing
import threading
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from multion.common.processes import ignore_stop_signals
from multion.config.datasets import variant_name
from multion.config.episode import Episode
from multion.leaderboard import hidden_entry
from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.scenes.registry import house_id, sized_house_id

HIDDEN_HOUSE_BASE = 10**9
"""Hidden house numbers start here, far from the packaged splits' 0–89."""
HIDDEN_HOUSE_SPAN = 10**12
SAMPLE_TRIES = 8
"""Fresh episodes: sampling attempts (each of ``EpisodeConstraints.max_tries`` starts) before
giving up on a house (the packaged generator allows 4)."""
T = TypeVar("T")
log = logging.getLogger("multion.leaderboard")


def derived_int(secret: str, label: str, bits: int = 63) -> int:
    """A number only the secret's holder can compute: HMAC-SHA256(secret, label) as an int."""
    digest = hmac.new(secret.encode("utf-8"), label.encode("utf-8"), hashlib.sha256).digest()
    return int.from_bytes(digest[:8], "big") >> (64 - bits)


# ---------------------------------------------------------------------- houses
def challenge_houses(challenge: Challenge) -> dict[tuple[str, str], list[str]]:
    """The hidden house ids of every (track, phase), all distinct.

    Drawn in the sorted order of (track, phase) names, so the order of the challenge file does
    not matter; a number already taken (by chance: about one in 10⁹ for a big challenge) is
    drawn again with a counter in its label.
    """
    taken: set[int] = set()
    houses: dict[tuple[str, str], list[str]] = {}
    for track in sorted(challenge.tracks, key=lambda t: t.name):
        for phase in sorted(track.phases, key=lambda p: p.name):
            ids = []
            for index in range(phase.houses):
                label, attempt = f"house/{track.name}/{phase.name}/{index}", 0
                number = _house_number(challenge.secret, label)
                while number in taken:
                    attempt += 1
                    number = _house_number(challenge.secret, f"{label}/{attempt}")
                taken.add(number)
                ids.append(_house_id(challenge, number, label))
            houses[(track.name, phase.name)] = ids
    return houses


def _house_number(secret: str, label: str) -> int:
    return HIDDEN_HOUSE_BASE + derived_int(secret, label) % HIDDEN_HOUSE_SPAN


def _house_id(challenge: Challenge, number: int, label: str) -> str:
    if challenge.hidden.rooms is None:
        return house_id(number)  # the generator draws the rooms, as for the packaged houses
    low, high = challenge.hidden.rooms
    rooms = low + derived_int(challenge.secret, f"rooms/{label}") % (high - low + 1)
    return sized_house_id(number, rooms)


def hidden_houses(challenge: Challenge, track: Track, phase: Phase) -> list[str]:
    """The hidden house ids of (track, phase)."""
    return challenge_houses(challenge)[(track.name, phase.name)]


# ---------------------------------------------------------------------- episodes
def generate_hidden_episodes(challenge: Challenge, track: Track, phase: Phase) -> list[Episode]:
    """The fixed episode set of (track, phase), in canonical order (runs shuffle it).
    Blocking: it builds the phase's houses in this process."""
    seed = derived_int(challenge.secret, f"episodes/{track.name}/{phase.name}")
    return hidden_entry.fixed_episode_set(
        track.num_goals,
        f"hidden-{phase.name}",
        phase.episodes,
        seed,
        hidden_houses(challenge, track, phase),
        track.num_distractors,
    )


def run_order(challenge: Challenge, run_id: str, count: int) -> list[int]:
    """The order in which a run of a fixed phase plays its ``count`` episodes."""
    rng = np.random.default_rng(derived_int(challenge.secret, f"order/{run_id}"))
    return [int(i) for i in rng.permutation(count)]


def fresh_house_plan(challenge: Challenge, track: Track, phase: Phase, run_id: str) -> list[int]:
    """The house (index into :func:`hidden_houses`) of each episode of a fresh run: every house
    as often as the others (±1), in an order drawn for the run."""
    plan = np.arange(phase.episodes) % phase.houses
    rng = np.random.default_rng(
        derived_int(challenge.secret, f"plan/{track.name}/{phase.name}/{run_id}")
    )
    rng.shuffle(plan)
    return [int(h) for h in plan]


def fresh_episode_id(run_id: str, position: int) -> str:
    """The id of episode ``position`` of a fresh run (known before it is drawn)."""
    return f"run-{run_id}-{position:05d}"


def fresh_episode(
    challenge: Challenge,
    track: Track,
    phase: Phase,
    houses: list[str],
    run_id: str,
    position: int,
) -> Episode:
    """Episode ``position`` of fresh run ``run_id``: a pure function of the secret, the run
    id and the position (``houses``: the phase's :func:`hidden_houses`, which its callers
    keep). Blocking (the house's grid may have to be built, in this process)."""
    scene = houses[fresh_house_plan(challenge, track, phase, run_id)[position]]
    label = f"episode/{track.name}/{phase.name}/{run_id}/{position}"
    episode = hidden_entry.episode_in_house(
        scene, track.num_goals, track.num_distractors, derived_int(challenge.secret, label),
        fresh_episode_id(run_id, position), SAMPLE_TRIES,
    )  # fmt: skip
    if episode is not None:
        return episode
    raise RuntimeError(
        f"cannot place {variant_name(track.num_goals, track.num_distractors)} goals in a hidden "
        "house of "
        f"{track.name}/{phase.name}"
    )


# ---------------------------------------------------------------------- the service's view
@dataclass(frozen=True)
class RunDraw:
    """Which episodes a run plays: its id, ``fresh`` or ``fixed``, and its stored order
    (fixed: indices into the phase's set; fresh: its positions 0..n-1)."""

    run_id: str
    episode_set: str
    order: tuple[int, ...]


class HiddenEpisodes:
    """The hidden episodes of a server's runs: fixed sets generated once and kept, fresh
    episodes drawn one at a time as runs reach them.

    With ``in_subprocess`` the work happens in one helper process kept for the server's
    lifetime (with its grids): building houses and sampling hold the GIL for seconds, which
    would stall the server's event loop.
    """

    def __init__(self, challenge: Challenge, in_subprocess: bool = True) -> None:
        self.challenge = challenge
        self.in_subprocess = in_subprocess
        self.houses = challenge_houses(challenge)
        self._sets: dict[tuple[str, str], list[Episode]] = {}
        self._lock = threading.Lock()
        self._pool_lock = threading.Lock()
        self._pool: ProcessPoolExecutor | None = None

    # Every method below blocks: call it from a thread.
    def phase_set(self, track: Track, phase: Phase) -> list[Episode]:
        """The fixed episode set of (track, phase), generated on first need."""
        key = (track.name, phase.name)
        with self._lock:
            if key not in self._sets:
                generate = functools.partial(generate_hidden_episodes, self.challenge, track, phase)
                self._sets[key] = self._run(generate)
            return self._sets[key]

    def episode(self, track: Track, phase: Phase, draw: RunDraw, position: int) -> Episode:
        """The episode a run plays at ``position``."""
        if draw.episode_set == "fixed":
            return self.phase_set(track, phase)[draw.order[position]]
        houses = self.houses[(track.name, phase.name)]
        draw_one = functools.partial(
            fresh_episode, self.challenge, track, phase, houses, draw.run_id, position
        )
        return self._run(draw_one)

    def episode_ids(self, track: Track, phase: Phase, draw: RunDraw) -> list[str]:
        """The ids of a run's episodes in play order, without drawing fresh ones."""
        if draw.episode_set == "fixed":
            fixed = self.phase_set(track, phase)
            return [fixed[i].episode_id for i in draw.order]
        return [fresh_episode_id(draw.run_id, p) for p in range(len(draw.order))]

    def house_of(self, track: Track, phase: Phase, draw: RunDraw) -> list[int]:
        """The house (index into the phase's hidden houses) of each position of a run."""
        if draw.episode_set == "fixed":
            number = {h: k for k, h in enumerate(self.houses[(track.name, phase.name)])}
            fixed = self.phase_set(track, phase)
            return [number[fixed[i].scene_id] for i in draw.order]
        return fresh_house_plan(self.challenge, track, phase, draw.run_id)

    def warm(self, track: Track, phase: Phase) -> None:
        """Prepare a phase before its first run: its fixed set, or its houses' grids."""
        if phase.episode_set == "fixed":
            self.phase_set(track, phase)
        else:
            self._run(
                functools.partial(hidden_entry.build_grids, self.houses[(track.name, phase.name)])
            )

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None

    def _run(self, work: Callable[[], T]) -> T:
        """``work`` (a module-level function with its arguments: picklable) in the helper, or
        in this process without ``in_subprocess``."""
        if not self.in_subprocess:
            return work()
        for attempt in range(2):
            pool = self._live_pool()
            try:
                return pool.submit(work).result()
            except BrokenProcessPool:
                # The helper died (killed, out of memory): a broken pool stays broken, so a
                # new one takes its place, and the call is tried once more in it.
                log.warning("the hidden-episode helper died; starting a new one")
                self._drop_pool(pool)
                if attempt == 1:
                    raise
        raise AssertionError("unreachable")

    def _live_pool(self) -> ProcessPoolExecutor:
        with self._pool_lock:
            if self._pool is None:
                spawn = multiprocessing.get_context("spawn")
                self._pool = ProcessPoolExecutor(1, spawn, initializer=ignore_stop_signals)
            return self._pool

    def _drop_pool(self, pool: ProcessPoolExecutor) -> None:
        with self._pool_lock:
            if self._pool is pool:
                self._pool = None
        pool.shutdown(wait=False, cancel_futures=True)
