"""Figure 3 style pictures of a run's first episodes, drawn by replaying the stored actions.

Only phases with per-episode feedback (minival) show them, and only the first
:data:`PICTURES_PER_RUN` episodes of a run: each costs a house build and a replay. They are drawn
one at a time in a separate process (house building holds the GIL for seconds and would stall
the server's event loop), and the PNGs are kept in a small cache.
"""

from __future__ import annotations

import asyncio
import io
import multiprocessing
import resource
from collections import OrderedDict
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from multion.api.config_io import session_config_from_dict
from multion.leaderboard.challenge import Phase, Track
from multion.leaderboard.models import EpisodeRecord
from multion.pictures import episode_picture, gps_to_world
from multion.processes import die_with_parent
from multion.task.env import MultiONEnv
from multion.task.episode import Episode

PICTURES_PER_RUN = 3
CACHED_PICTURES = 64
PIXELS_PER_METRE = 24
DRAWER_MEMORY_BYTES = 3 * 2**30
"""Address-space limit of the drawing process (a house of 8 rooms needs well under a GiB)."""


def _start_drawer() -> None:
    """In the drawing process: end with the server, and never take more than its limit."""
    die_with_parent()
    resource.setrlimit(resource.RLIMIT_AS, (DRAWER_MEMORY_BYTES, DRAWER_MEMORY_BYTES))


@dataclass(frozen=True)
class EpisodeReplay:
    """What a picture is drawn from: a stored episode of a run, in its track's environment."""

    track: Track
    phase: Phase
    maps: dict[str, Any]
    episode: Episode
    actions: str
    metrics: dict[str, Any]
    label: str

    def draw(self) -> bytes:
        """Replay the actions (GPS only: nothing rendered) and draw the episode as a PNG."""
        config_dict = self.track.env_config(self.phase, ("gps",), self.maps)
        config, _ = session_config_from_dict(config_dict)
        env = MultiONEnv(config, episodes=[self.episode])
        try:
            observation, _ = env.reset(options={"episode_index": 0})
            gps = [np.asarray(observation["gps"], dtype=np.float64)]
            for action in self.actions:
                observation, *_ = env.step(int(action))
                gps.append(np.asarray(observation["gps"], dtype=np.float64))
            path = gps_to_world(np.asarray(gps), self.episode)
            image = episode_picture(
                self.episode, path, self.metrics, env.sim, PIXELS_PER_METRE, label=self.label
            )
        finally:
            env.close()
        buffer = io.BytesIO()
        image.save(buffer, format="PNG", optimize=True)
        return buffer.getvalue()


def pictured(records: Sequence[EpisodeRecord]) -> list[EpisodeRecord]:
    """The episodes of a run that get a picture: its first played ones."""
    return [r for r in records if r.actions][:PICTURES_PER_RUN]


class EpisodePictures:
    """Draws pictures in one helper process, one at a time, and caches the last ones."""

    def __init__(self) -> None:
        self._pool: ProcessPoolExecutor | None = None
        self._lock = asyncio.Lock()
        self._cache: OrderedDict[tuple[str, int], bytes] = OrderedDict()

    async def get(self, key: tuple[str, int], replay: EpisodeReplay) -> bytes:
        async with self._lock:
            if key in self._cache:
                self._cache.move_to_end(key)
                return self._cache[key]
            if self._pool is None:
                spawn = multiprocessing.get_context("spawn")
                self._pool = ProcessPoolExecutor(1, spawn, initializer=_start_drawer)
            png = await asyncio.wrap_future(self._pool.submit(replay.draw))
            self._cache[key] = png
            while len(self._cache) > CACHED_PICTURES:
                self._cache.popitem(last=False)
            return png

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
