"""One headless OpenGL context per process, opened on first use through EGL.

EGL gives a context without a display: NVIDIA's driver on a GPU machine, Mesa's llvmpipe on a
CPU. Mesa rasterises with ``LP_NUM_THREADS`` threads; here it defaults to 0 (draw in the
calling thread), so a simulator process keeps to one core, as TinyRenderer does; on the
project's 2-core machines it was also the fastest setting at 36² and 128² (set
``LP_NUM_THREADS`` before the first context to change it; docs/rendering.md). A machine without EGL gets one line
saying what to install, never a crash (:func:`gl_unavailable_reason`).
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from multion.config.sim import EGL_PACKAGES

if TYPE_CHECKING:
    import moderngl

GL_VERSION = 330
"""The OpenGL version the renderer's shaders need (3.3 core)."""

_lock = threading.RLock()
_context: moderngl.Context | None = None
_failure: str | None = None


class GLUnavailableError(ValueError):
    """``camera.renderer = "gl"`` where no OpenGL 3.3 context opens."""


def gl_unavailable_reason() -> str | None:
    """None where an OpenGL context opens in this process, else one line saying why not and
    what to install (the answer is kept: the context is opened once per process)."""
    try:
        _open()
    except GLUnavailableError as error:
        return str(error)
    return None


def gl_unavailable_reason_in_child(timeout_s: float = 60.0) -> str | None:
    """:func:`gl_unavailable_reason` answered by a short-lived child process, so that this one
    keeps no context: a context holds ~60 MiB resident and ~280 MiB of address space for the
    process's life, which a simulator worker that never renders with gl should not carry."""
    if _context is not None or _failure is not None:  # known here already
        return gl_unavailable_reason()
    ask = "from multion.sim.gl.context import gl_unavailable_reason as r; print(r() or '')"
    try:
        child = subprocess.run(
            [sys.executable, "-c", ask], capture_output=True, text=True, timeout=timeout_s
        )
    except subprocess.TimeoutExpired:
        return f"camera.renderer 'gl': no answer from the OpenGL probe within {timeout_s:.0f} s"
    lines = child.stdout.strip().splitlines()
    if child.returncode != 0:
        error = (child.stderr.strip().splitlines() or ["no message"])[-1]
        return f"camera.renderer 'gl': the OpenGL probe failed ({error:.120})"
    return (lines[-1] if lines else "") or None


def _open() -> moderngl.Context:
    global _context, _failure
    with _lock:
        if _context is not None:
            return _context
        if _failure is not None:
            raise GLUnavailableError(_failure)
        os.environ.setdefault("LP_NUM_THREADS", "0")
        try:
            import moderngl

            context = moderngl.create_standalone_context(backend="egl")  # type: ignore[arg-type]  # stub lacks backend
            if context.version_code < GL_VERSION:
                version = context.version_code
                context.release()
                raise RuntimeError(f"OpenGL {version // 100}.{version % 100 // 10} < 3.3")
        except Exception as error:  # moderngl / glcontext raise plain Exceptions
            detail = (
                str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
            )
            _failure = (
                f"camera.renderer 'gl': no OpenGL 3.3 context through EGL ({detail:.120}). "
                f"Without a GPU install Mesa's EGL (Debian/Ubuntu: apt-get install {EGL_PACKAGES}); "
                "on a GPU machine NVIDIA's driver; or use camera.renderer 'tiny'."
            )
            raise GLUnavailableError(_failure) from None
        # release it from this thread, so that any thread may make it current (current())
        with context:
            pass
        _context = context
        return context


@contextmanager
def current() -> Iterator[moderngl.Context]:
    """The process's context, current in this thread for the block (one thread at a time)."""
    context = _open()
    with _lock, context:
        yield context
