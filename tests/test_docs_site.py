"""The docs site (issue 52): ``mkdocs build --strict`` builds it from docs/ (no broken link or
anchor, every page in the nav, the API reference generated from the docstrings), and its home
page, a tutorial and the API reference are looked at in the system Chromium at 1280 and 390 px:
nothing wider than the screen, and axe-core finds no violation.

``MULTION_DOCS_SCREENSHOTS=DIR`` keeps the screenshots in DIR (they are taken in any case)."""

from __future__ import annotations

import functools
import http.server
import os
import re
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml  # mkdocs' own dependency (PyYAML)

from chromium import chromium, require_axe_core

pytest.importorskip("mkdocs", reason="the docs extra: pip install -e '.[docs]'")

ROOT = Path(__file__).resolve().parents[1]
MKDOCS = [sys.executable, "-m", "mkdocs"]
QUIET = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
LOOKED_AT = {"home": "", "tutorial": "tutorials/evaluate/", "reference": "reference/client/"}
WIDTHS = {"1280": (1280, 800), "390": (390, 844)}


def build(config: Path, site: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*MKDOCS, "build", "--strict", "--config-file", str(config), "--site-dir", str(site)],
        capture_output=True, text=True, timeout=600, env=QUIET,
    )  # fmt: skip


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    done = build(ROOT / "mkdocs.yml", out)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-4000:]
    return out


def test_the_site_builds_strictly_with_every_part(site: Path) -> None:
    for page in ("index.html", "getting-started/index.html", "tutorials/train/index.html"):
        assert (site / page).is_file(), page
    client = (site / "reference" / "client" / "index.html").read_text(encoding="utf-8")
    # generated from the docstrings: RemoteEnv's and RunEnv's own words, not only their names
    assert "Gymnasium" in client and "RunEnv" in client and "def reset" not in client
    assert 'id="multion_client.env.RemoteEnv"' in client
    config = (site / "reference" / "config" / "index.html").read_text(encoding="utf-8")
    assert 'id="multion.config.task.TaskConfig.max_steps"' in config  # every field, by name
    http_routes = (site / "reference" / "http" / "index.html").read_text(encoding="utf-8")
    assert "/openapi.json" in http_routes


def test_a_broken_anchor_fails_the_strict_build(tmp_path: Path) -> None:
    """The same validation settings, on two pages, one linking to an anchor the other lacks."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text("# Home\n\nSee [the part](other.md#no-such-part).\n")
    (docs / "other.md").write_text("# Other\n\n## A part\n")
    config.update(docs_dir=str(docs), nav=["index.md", "other.md"], plugins=["search"])
    config["theme"]["custom_dir"] = str(ROOT / config["theme"]["custom_dir"])
    for key in ("not_in_nav", "extra_css"):
        config.pop(key)
    (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(config))
    done = build(tmp_path / "mkdocs.yml", tmp_path / "site")
    assert done.returncode != 0 and "no-such-part" in done.stderr, done.stderr[-2000:]
    (docs / "index.md").write_text("# Home\n\nSee [the part](other.md#a-part).\n")
    assert build(tmp_path / "mkdocs.yml", tmp_path / "site").returncode == 0


@pytest.fixture(scope="module")
def served(site: Path) -> Iterator[str]:
    handler = functools.partial(QuietHandler, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
        pass


@pytest.mark.parametrize("width", WIDTHS)
def test_the_pages_fit_the_screen_and_axe_finds_nothing(
    served: str, width: str, tmp_path: Path
) -> None:
    axe = require_axe_core()
    shots = Path(os.environ.get("MULTION_DOCS_SCREENSHOTS") or tmp_path)
    shots.mkdir(parents=True, exist_ok=True)
    w, h = WIDTHS[width]
    found: dict[str, Any] = {}
    with chromium() as browser:
        page = browser.new_page(viewport={"width": w, "height": h})
        for name, path in LOOKED_AT.items():
            response = page.goto(served + path, wait_until="load")
            assert response is not None and response.status == 200, path
            assert page.title().endswith("MultiON on PyBullet"), page.title()
            page.screenshot(path=str(shots / f"docs-{name}-{width}.png"), full_page=True)
            overflow = page.evaluate(
                "document.documentElement.scrollWidth - document.documentElement.clientWidth"
            )
            assert overflow <= 0, f"{path} is {overflow} px wider than a {width} px screen"
            page.evaluate(axe)
            violations = page.evaluate(
                "axe.run(document).then(r => r.violations.map("
                "v => [v.id, v.impact, v.nodes.map(n => n.target.join(' ')).slice(0, 3)]))"
            )
            if violations:
                found[path or "/"] = violations
    assert found == {}, found


def test_the_readme_is_a_first_screen_whose_links_lead_into_the_site() -> None:
    """The README stays short (what this is, the two commands, the two ten-line examples, links),
    and every relative link in it names a file that exists (GitHub shows it; the site does not
    build it, so ``--strict`` cannot check it)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150
    links = re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", text)
    assert len(links) >= 20
    missing = [link for link in links if not (ROOT / link).exists()]
    assert missing == []
    nav = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))["nav"]
    pages = set(re.findall(r"[\w/.-]+\.md", str(nav)))
    assert {link.removeprefix("docs/") for link in links if link.endswith(".md")} <= pages
