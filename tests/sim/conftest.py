"""The ``egl`` fixture: skips a test where PyBullet's EGL plugin does not load, or fails it
when ``MULTION_REQUIRE_EGL=1`` (set by CI, which installs Mesa's EGL)."""

from __future__ import annotations

import os

import pytest

from multion.sim import camera as camera_module
from multion.sim.camera import EGL_PACKAGES

REQUIRE_EGL = os.environ.get("MULTION_REQUIRE_EGL") == "1"


@pytest.fixture(scope="module")
def egl() -> None:
    if camera_module.resolve_renderer("auto") == "egl":
        return
    message = (
        f"PyBullet's EGL plugin does not load here; install Mesa's EGL "
        f"(apt-get install {EGL_PACKAGES}) or NVIDIA's driver"
    )
    if REQUIRE_EGL:
        pytest.fail(f"MULTION_REQUIRE_EGL=1 but {message}")
    pytest.skip(message)
