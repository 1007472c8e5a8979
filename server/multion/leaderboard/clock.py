"""The time that run and lane deadlines are measured against.

:class:`~multion.leaderboard.runs.RunService` reads the time only through a :class:`Clock`:
the server's is :class:`SystemClock` (the wall clock, UTC); a test passes a
:class:`ManualClock` and moves it on with ``advance`` instead of sleeping until an episode's
step budget or a run's time budget has passed.
"""

from __future__ import annotations

import datetime as dt
import threading
from typing import Protocol

from multion.leaderboard.models import utcnow


class Clock(Protocol):
    """Where deadlines come from: ``now()`` is the current time, timezone-aware UTC."""

    def now(self) -> dt.datetime: ...


class SystemClock:
    """The wall clock (what a server runs on)."""

    def now(self) -> dt.datetime:
        return utcnow()


class ManualClock:
    """A clock that stands still until ``advance`` moves it (for tests); it starts at the wall
    clock's time, so dates in the challenge file (``sealed_until``) compare as on a server."""

    def __init__(self, start: dt.datetime | None = None) -> None:
        self._now = start or utcnow()
        self._lock = threading.Lock()  # a test thread advances it while the server reads it

    def now(self) -> dt.datetime:
        with self._lock:
            return self._now

    def advance(self, seconds: float) -> None:
        """Move the time on by ``seconds`` (≥ 0: deadlines never come back)."""
        if seconds < 0:
            raise ValueError(f"a clock only moves forward, got {seconds} s")
        with self._lock:
            self._now += dt.timedelta(seconds=seconds)
