"""Whose turn it is at a simulator worker, which answers one request at a time.

Steps go before the slower requests waiting with them (resets, which may switch houses, and
session creations), so that a crowd's episode starts do not hold up the steps of everyone else
on the worker: in ``multion bench --only participants`` (48 at once, episodes of one length,
so their resets come together) the slowest 1 % of steps were nearly all the first step of an
episode, queued behind the other participants' resets (issue 53 item 7). A slow request is
passed by at most :data:`MAX_OVERTAKES` steps, so it is never starved: it waits for at most
that many steps more than in arrival order.
"""

from __future__ import annotations

import asyncio
from collections import deque
from dataclasses import dataclass, field

MAX_OVERTAKES = 16
"""How many steps may go before one waiting slower request."""


@dataclass
class _Waiter:
    future: asyncio.Future[None]
    urgent: bool
    overtakes_left: int = field(default=MAX_OVERTAKES)


class TurnQueue:
    """A lock whose waiters are served in arrival order, except that urgent ones (steps) go
    before the others, each of which may be passed :data:`MAX_OVERTAKES` times.

    ``async with turns.turn(urgent):`` holds the worker for one request."""

    def __init__(self) -> None:
        self._held = False
        self._waiters: deque[_Waiter] = deque()

    @property
    def waiting(self) -> int:
        return len(self._waiters)

    def turn(self, urgent: bool) -> _Turn:
        return _Turn(self, urgent)

    async def acquire(self, urgent: bool) -> None:
        if not self._held and not self._waiters:
            self._held = True
            return
        waiter = _Waiter(asyncio.get_running_loop().create_future(), urgent)
        self._waiters.append(waiter)
        try:
            await waiter.future
        except BaseException:
            if waiter.future.done() and not waiter.future.cancelled():
                self._release()  # it was given the turn as it was cancelled: pass it on
            else:
                self._waiters.remove(waiter)
            raise

    def release(self) -> None:
        self._release()

    def _release(self) -> None:
        chosen = self._next()
        if chosen is None:
            self._held = False
            return
        self._waiters.remove(chosen)
        chosen.future.set_result(None)  # the turn passes on: still held

    def _next(self) -> _Waiter | None:
        """The first urgent waiter if every slower one before it may still be passed; else
        the first waiter."""
        if not self._waiters:
            return None
        passed: list[_Waiter] = []
        for waiter in self._waiters:
            if waiter.urgent:
                for slow in passed:
                    slow.overtakes_left -= 1
                return waiter
            if waiter.overtakes_left <= 0:
                break
            passed.append(waiter)
        return self._waiters[0]


class _Turn:
    def __init__(self, queue: TurnQueue, urgent: bool) -> None:
        self.queue, self.urgent = queue, urgent

    async def __aenter__(self) -> None:
        await self.queue.acquire(self.urgent)

    async def __aexit__(self, *exc: object) -> None:
        self.queue.release()
