"""The path each environment of a session has walked in its current episode, for the live view's
map (as the episode videos draw it): the ``gps`` readings of its answers since the episode
began. Kept only where the live view is on, and only for sessions that have ``gps``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from multion_client.wire import decode_small_arrays

MAX_POINTS = 10_000
"""Points kept per environment at most (an episode's step limit is far below): beyond it the
oldest are dropped, so a session that never resets holds a bounded trail."""

GPS_BYTES_AT_MOST = 256
"""A ``gps`` reading is 2 floats (21 bytes encoded); larger arrays are skipped undecoded."""


@dataclass
class Trail:
    """One environment's readings in its current episode (GPS: metres from its start)."""

    episode_id: str = ""
    points: list[tuple[float, float]] = field(default_factory=list)

    def add(self, episode_id: str, gps: tuple[float, float], new_episode: bool) -> None:
        if new_episode or episode_id != self.episode_id:
            self.episode_id, self.points = episode_id, []
        if self.points and self.points[-1] == gps:
            return  # a turn or a blocked step: no new point
        self.points.append(gps)
        if len(self.points) > MAX_POINTS:
            del self.points[: len(self.points) - MAX_POINTS]


def extend_trails(trails: list[Trail], answer: bytes, reset: bool) -> list[Trail]:
    """``trails`` (one per environment) with the readings of ``answer`` (a reset's or a step's
    encoded reply); an answer without ``gps`` leaves them as they are."""
    decoded = decode_small_arrays(answer, GPS_BYTES_AT_MOST)  # the images are not read
    observations, infos = decoded["observations"], decoded["infos"]
    if len(trails) != len(observations):
        trails = [Trail() for _ in observations]
    for trail, observation, info in zip(trails, observations, infos, strict=True):
        gps = observation.get("gps")
        if not isinstance(gps, np.ndarray) or gps.size < 2:
            continue
        x, y = (float(v) for v in np.ravel(gps)[:2])
        trail.add(str(info.get("episode_id", "")), (x, y), reset)
    return trails
