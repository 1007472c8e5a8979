"""Hidden episodes and houses, generated on the server from the challenge's secret.

Every number here comes from ``HMAC-SHA256(secret, label)``: the houses of a phase are
``house-N-rK`` with N ≥ 10⁹ drawn from the secret (the packaged splits use houses 0–89), and the
episodes of a (track, phase) are sampled in them with a seed drawn from the secret. Nothing is
written to disk; the same secret always gives the same houses and episodes, so a stored run can
be replayed and re-scored later. Without the secret the house numbers cannot be guessed.
"""

from __future__ import annotations

import hashlib
import hmac
import multiprocessing
import threading
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.processes import die_with_parent
from multion.scenes.registry import sized_house_id
from multion.task.episode import Episode
from multion.task.generate import generate_episodes

HIDDEN_HOUSE_BASE = 10**9
"""Hidden house numbers start here, far from the packaged splits' 0–89."""
HIDDEN_HOUSE_SPAN = 10**12


def derived_int(secret: str, label: str, bits: int = 63) -> int:
    """A number only the secret's holder can compute: HMAC-SHA256(secret, label) as an int."""
    digest = hmac.new(secret.encode("utf-8"), label.encode("utf-8"), hashlib.sha256).digest()
    return int.from_bytes(digest[:8], "big") >> (64 - bits)


def hidden_houses(challenge: Challenge, phase: Phase) -> list[str]:
    """The hidden house ids of ``phase`` (shared by its tracks), with secret room counts."""
    low, high = challenge.hidden.rooms
    houses = []
    for index in range(phase.houses):
        number = (
            HIDDEN_HOUSE_BASE
            + derived_int(challenge.secret, f"house/{phase.name}/{index}") % HIDDEN_HOUSE_SPAN
        )
        rooms = low + derived_int(challenge.secret, f"rooms/{phase.name}/{index}") % (
            high - low + 1
        )
        houses.append(sized_house_id(number, rooms))
    return houses


def generate_hidden_episodes(challenge: Challenge, track: Track, phase: Phase) -> list[Episode]:
    """The hidden episodes of (track, phase), in their canonical order (runs shuffle them)."""
    seed = derived_int(challenge.secret, f"episodes/{track.name}/{phase.name}")
    return generate_episodes(
        track.num_goals,
        f"hidden-{phase.name}",
        phase.episodes,
        seed=seed,
        scenes=hidden_houses(challenge, phase),
        progress=False,
    )


def run_order(challenge: Challenge, run_id: str, count: int) -> list[int]:
    """The order in which run ``run_id`` plays the ``count`` episodes: a per-run shuffle."""
    rng = np.random.default_rng(derived_int(challenge.secret, f"order/{run_id}"))
    return [int(i) for i in rng.permutation(count)]


class HiddenEpisodes:
    """The hidden episodes of every (track, phase), generated once on first need and kept.

    With ``in_subprocess`` they are generated in a fresh process: building houses holds the
    GIL for seconds, which would stall a server's event loop.
    """

    def __init__(self, challenge: Challenge, in_subprocess: bool = True) -> None:
        self.challenge = challenge
        self.in_subprocess = in_subprocess
        self._cache: dict[tuple[str, str], list[Episode]] = {}
        self._lock = threading.Lock()

    def get(self, track: Track, phase: Phase) -> list[Episode]:
        """Blocking (house building and sampling take seconds): call it from a thread."""
        key = (track.name, phase.name)
        with self._lock:
            if key not in self._cache:
                if self.in_subprocess:
                    spawn = multiprocessing.get_context("spawn")
                    with ProcessPoolExecutor(1, spawn, initializer=die_with_parent) as pool:
                        future = pool.submit(generate_hidden_episodes, self.challenge, track, phase)
                        self._cache[key] = future.result()
                else:
                    self._cache[key] = generate_hidden_episodes(self.challenge, track, phase)
            return self._cache[key]
