"""``wait_until``: the one polling loop of the tests (a server starting, a background task
finishing, a process going away); ``answers``: its usual predicate for a server."""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable
from typing import Any, TypeVar

import httpx

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


def answers(url: str, process: subprocess.Popen[Any] | None = None, method: str = "GET") -> bool:
    """Whether ``url`` answers 200 now; fails at once if ``process`` (the server behind it) has
    exited, with what it printed to the pipes it has."""
    if process is not None and process.poll() is not None:
        raise AssertionError(
            f"{process.args!r:.200} exited with {process.returncode}: {process.communicate()}"
        )
    try:
        return httpx.request(method, url, timeout=1.0).status_code == 200
    except httpx.TransportError:
        return False
