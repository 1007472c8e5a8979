"""Child processes that end with their parent, and a parent that ends cleanly on SIGTERM."""

from __future__ import annotations

import ctypes
import ctypes.util
import signal
import sys
from types import FrameType

_PR_SET_PDEATHSIG = 1


def die_with_parent(signum: int = signal.SIGTERM) -> None:
    """Ask Linux to send ``signum`` to this process when its parent dies (even by SIGKILL), so
    a killed ``multion eval`` or server leaves no orphan behind. A no-op elsewhere."""
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signum, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def exit_on_sigterm() -> None:
    """Turn SIGTERM into ``SystemExit(143)``, so ``finally`` blocks and context managers stop
    the servers, workers and vector envs a command started (Python's default for SIGTERM ends
    the process at once and leaves them running). Further SIGTERMs are ignored while it
    cleans up; SIGKILL still ends it, and :func:`die_with_parent` then ends its children."""

    def handler(signum: int, frame: FrameType | None) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, handler)
