"""The ``egl`` and ``gl`` fixtures: skip a test where PyBullet's EGL plugin does not load (or
where no OpenGL context opens through EGL), or fail it when ``MULTION_REQUIRE_EGL=1`` (set by
CI, which installs Mesa's EGL)."""

from __future__ import annotations

import os

import pytest

from multion.sim import camera as camera_module
from multion.sim.camera import EGL_PACKAGES
from multion.sim.gl.context import gl_unavailable_reason

REQUIRE_EGL = os.environ.get("MULTION_REQUIRE_EGL") == "1"


@pytest.fixture(scope="module")
def egl() -> None:
    if camera_module.egl_plugin_loads():
        return
    message = (
        f"PyBullet's EGL plugin does not load here; install Mesa's EGL "
        f"(apt-get install {EGL_PACKAGES}) or NVIDIA's driver"
    )
    if REQUIRE_EGL:
        pytest.fail(f"MULTION_REQUIRE_EGL=1 but {message}")
    pytest.skip(message)


@pytest.fixture(scope="module")
def gl() -> None:
    reason = gl_unavailable_reason()
    if reason is None:
        return
    if REQUIRE_EGL:
        pytest.fail(f"MULTION_REQUIRE_EGL=1 but {reason}")
    pytest.skip(reason)
