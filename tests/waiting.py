"""``wait_until``: the one polling loop of the tests (a server starting, a background task
finishing, a process going away)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def wait_until(
    predicate: Callable[[], T],
    timeout: float = 20.0,
    interval: float = 0.1,
    message: str = "the condition",
) -> T:
    """Call ``predicate`` every ``interval`` seconds until it returns something true, and
    return that; fail the test after ``timeout`` seconds with ``message`` (what was awaited)
    and the predicate's last answer."""
    deadline = time.monotonic() + timeout
    while True:
        result = predicate()
        if result:
            return result
        if time.monotonic() > deadline:
            raise AssertionError(
                f"timed out after {timeout:g} s waiting for {message} (last: {result!r:.200})"
            )
        time.sleep(interval)
