"""PyBullet, without the lines its C code prints on every command.

PyBullet prints ``pybullet build time: …`` when it is imported, and its EGL plugin prints the
device it chose when loaded (``EGL device choice …``, the OpenGL vendor and version) and
``Destroy EGL OpenGL window.`` when its client disconnects. C code writes them to the process's
file descriptors 1 and 2, past Python's ``sys.stdout``, so :func:`c_output_silenced` points
those descriptors at ``/dev/null`` around the calls that print. Import ``pybullet`` from here.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator


def _flush_c_streams() -> None:
    """Write out what C's stdio holds (stdout is block-buffered when it is not a terminal, so
    a line printed while silenced would otherwise come out after)."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def c_output_silenced() -> Iterator[None]:
    """Discard what is written to file descriptors 1 and 2 (stdout, stderr) for the duration."""
    for stream in (sys.stdout, sys.stderr):
        if stream is not None:
            with contextlib.suppress(OSError, ValueError):
                stream.flush()
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:  # no such descriptors: nothing to silence
        yield
        return
    _flush_c_streams()
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        yield
    finally:
        _flush_c_streams()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, null):
            os.close(fd)


with c_output_silenced():
    import pybullet

__all__ = ["c_output_silenced", "pybullet"]
