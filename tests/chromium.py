"""The system Chromium driven by Playwright, for the browser tests of the leaderboard pages and
the live view: skipped with a message naming what to install, required under
``MULTION_REQUIRE_BROWSER=1`` (set by ``.ci/run``)."""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterator
from typing import Any

import pytest

REQUIRE_BROWSER = "MULTION_REQUIRE_BROWSER"
BROWSER_HINT = (
    "needs Chromium and Playwright: `apt-get install chromium` (Debian) and "
    f"`pip install playwright` (in the dev extra); {REQUIRE_BROWSER}=1 (set by .ci/run) makes "
    "these tests required"
)
# No sandbox as root (CI); no background connections to Google's hosts (the network is closed).
CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-quic",
]  # fmt: skip


def chromium_path() -> str | None:
    """The system Chromium's executable, or None."""
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


@contextlib.contextmanager
def chromium() -> Iterator[Any]:
    """A launched headless Chromium, closed after; skips (or fails where required) without one."""
    executable = chromium_path()
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        executable = None
    if executable is None:
        if os.environ.get(REQUIRE_BROWSER) == "1":
            pytest.fail(BROWSER_HINT)
        pytest.skip(BROWSER_HINT)
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=executable, args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


def axe_core_script() -> str | None:
    """axe-core's script, if installed (optional): ``$MULTION_AXE_CORE``, or ``npm install
    axe-core`` at the repository's root (as .ci/run does)."""
    from pathlib import Path

    for candidate in (
        os.environ.get("MULTION_AXE_CORE", ""),
        str(Path(__file__).resolve().parents[1] / "node_modules" / "axe-core" / "axe.min.js"),
    ):
        if candidate and Path(candidate).is_file():
            return Path(candidate).read_text(encoding="utf-8")
    return None


def require_axe_core() -> str:
    """axe-core's script; skips without it, or fails under ``MULTION_REQUIRE_AXE=1``."""
    script = axe_core_script()
    if script is None:
        if os.environ.get("MULTION_REQUIRE_AXE") == "1":  # set by .ci/run
            pytest.fail("MULTION_REQUIRE_AXE=1 but axe-core is missing: npm install axe-core@4")
        pytest.skip("axe-core is optional: npm install axe-core@4 (or set MULTION_AXE_CORE)")
    return script
