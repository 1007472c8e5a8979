"""The live view of a session (``/v1/live/{id}``): in a real headless Chromium, the page follows
a client that steps; requests it must not answer get a clear 4xx.

Without Chromium or Playwright the browser test skips; ``MULTION_REQUIRE_BROWSER=1`` (set by
.ci/run) makes it required."""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest
from PIL import Image

from chromium import chromium
from multion.api.local_server import LocalServer
from multion.api.settings import ServerSettings
from multion_client.constants import Action
from multion_client.env import RemoteEnv

CONFIG = {
    "task": {"num_goals": 2},
    "sensors": ["rgb", "depth", "gps", "compass"],
    "camera": {"width": 32, "height": 32},
}


@pytest.fixture(scope="module")
def server() -> Iterator[LocalServer]:
    with LocalServer(workers=1) as local:  # listens on 127.0.0.1: the live view is on
        yield local


@pytest.fixture
def env(server: LocalServer) -> Iterator[RemoteEnv]:
    remote = RemoteEnv(server.url, CONFIG)
    try:
        yield remote
    finally:
        remote.close()


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with chromium() as launched:
        yield launched


def test_the_page_follows_a_client_that_steps(
    server: LocalServer, env: RemoteEnv, browser: Any
) -> None:
    page = browser.new_page()
    try:
        page.goto(f"{server.url}/v1/live/{env.session_id}")
        page.wait_for_selector("text=Waiting for the first reset")
        env.reset(options={"episode_index": 0})
        page.wait_for_function("document.body.dataset.step === '0'", timeout=10_000)
        first = page.get_attribute("#frame", "src")
        for _ in range(3):
            env.step(int(Action.TURN_LEFT))
        page.wait_for_function("document.body.dataset.step === '3'", timeout=10_000)
        assert "step 3, last action TURN_LEFT" in page.inner_text("#status")
        assert page.get_attribute("#frame", "src") != first
        page.wait_for_function(
            "document.getElementById('frame').complete && "
            "document.getElementById('frame').naturalWidth > 0"
        )
        assert "TURN_LEFT" in (page.get_attribute("#frame", "alt") or "")
        metrics = page.inner_text("#metrics")
        assert "steps" in metrics and "distance_to_goal" in metrics
    finally:
        page.close()


def test_the_picture_and_state_follow_the_session(server: LocalServer, env: RemoteEnv) -> None:
    base = f"{server.url}/v1/live/{env.session_id}"
    assert httpx.get(f"{base}/state").json() == {"started": False}
    assert httpx.get(f"{base}/frame.png").status_code == 409
    env.reset(options={"episode_index": 0})
    env.step(int(Action.MOVE_FORWARD))
    state = httpx.get(f"{base}/state").json()
    assert state["step"] == 1 and state["action"] == "MOVE_FORWARD"
    assert state["sensors"] == ["compass", "depth", "gps", "rgb"]
    answer = httpx.get(f"{base}/frame.png")
    assert answer.status_code == 200 and answer.headers["content-type"] == "image/png"
    with Image.open(io.BytesIO(answer.content)) as image:
        width, height = image.size
    assert height == 256 and width > 2 * 256  # RGB and depth scaled to 256, then the map


def test_requests_it_must_not_answer_get_clear_errors(server: LocalServer, env: RemoteEnv) -> None:
    base = f"{server.url}/v1/live/{env.session_id}"
    answer = httpx.get(f"{server.url}/v1/live/0123abcd/state")
    assert answer.status_code == 404 and "no session '0123abcd'" in answer.text
    answer = httpx.get(f"{base}/state", params={"env": 1})
    assert answer.status_code == 400 and "env must be in [0, 0], got 1" in answer.text
    answer = httpx.get(f"{base}/frame.png", headers={"X-Forwarded-For": "203.0.113.9"})
    assert answer.status_code == 403
    assert answer.json()["error"]["code"] == "live_view_local_only"
    assert httpx.get(base, headers={"Forwarded": "for=203.0.113.9"}).status_code == 403


def test_off_unless_the_server_is_local_or_asked() -> None:
    assert ServerSettings().live_view_on()  # auto on 127.0.0.1
    assert not ServerSettings(host="0.0.0.0").live_view_on()  # auto on a public address
    assert ServerSettings(host="0.0.0.0", live_view="local").live_view_on()
    assert not ServerSettings(live_view="off").live_view_on()
    with LocalServer(workers=1, options=["--live-view", "off"]) as off:
        answer = httpx.get(f"{off.url}/v1/live/0123abcd")
    assert answer.status_code == 403 and "--live-view local" in answer.text


def test_the_listing_links_each_environment_of_each_session(
    server: LocalServer, env: RemoteEnv
) -> None:
    answer = httpx.get(f"{server.url}/v1/live")
    assert answer.status_code == 200
    assert f'href="/v1/live/{env.session_id}?env=0"' in answer.text
    forwarded = httpx.get(f"{server.url}/v1/live", headers={"X-Real-IP": "203.0.113.9"})
    assert forwarded.status_code == 403


def test_a_leaderboard_runs_session_has_no_live_view() -> None:
    from types import SimpleNamespace

    from starlette.requests import Request

    from multion.api.routers.live import Refused, _viewed
    from multion.api.sessions import Session

    run_session = Session("run-session", 1, False, [], owner=None)  # what a run's session is
    plain = Session("plain-session", 2, False, [], owner="ip:127.0.0.1")
    registry = SimpleNamespace(sessions={s.session_id: s for s in (run_session, plain)})
    app = SimpleNamespace(state=SimpleNamespace(settings=ServerSettings(), registry=registry))
    scope = {"type": "http", "app": app, "client": ("127.0.0.1", 5000), "headers": []}
    assert _viewed(Request(scope), "plain-session", 1) is plain
    with pytest.raises(Refused, match="leaderboard runs have no live view") as refused:
        _viewed(Request(scope), "run-session", 0)
    assert refused.value.status == 403
    scope["client"] = ("192.0.2.4", 5000)  # another machine
    with pytest.raises(Refused, match="only requests from the server's own machine"):
        _viewed(Request(scope), "plain-session", 0)


AGENT_ORANGE = (245, 130, 20)


def _orange_pixels(png: bytes) -> int:
    with Image.open(io.BytesIO(png)) as image:
        pixels = np.asarray(image.convert("RGB"))
    return int(np.all(pixels == AGENT_ORANGE, axis=-1).sum())


def test_the_map_draws_the_path_walked_in_the_episode(server: LocalServer, env: RemoteEnv) -> None:
    """Issue 53 item 4: the live map drew the agent but not its path (the videos do)."""
    base = f"{server.url}/v1/live/{env.session_id}"
    env.reset(options={"episode_index": 0})
    at_start = httpx.get(f"{base}/frame.png", params={"part": "map"}, timeout=60)
    assert at_start.status_code == 200
    with Image.open(io.BytesIO(at_start.content)) as image:
        assert image.size[1] == 256 and image.size[0] <= 2 * 256  # the map alone
    walked = 0.0
    for action in [Action.MOVE_FORWARD] * 6 + [Action.TURN_LEFT] * 3 + [Action.MOVE_FORWARD] * 6:
        _, _, _, _, info = env.step(int(action))
        walked = float(info["metrics"]["path_length"])
    assert walked > 1.0  # it moved (a path to draw)
    moved = httpx.get(f"{base}/frame.png", params={"part": "map"}, timeout=60).content
    # the agent's arrow is the same size; the path walked adds its orange line
    assert _orange_pixels(moved) > _orange_pixels(at_start.content) + 50
    env.reset(options={"episode_index": 1})  # a new episode starts a new path
    again = httpx.get(f"{base}/frame.png", params={"part": "map"}, timeout=60).content
    assert _orange_pixels(again) < _orange_pixels(moved)
    views = httpx.get(f"{base}/frame.png", params={"part": "views"}, timeout=60)
    with Image.open(io.BytesIO(views.content)) as image:
        assert image.size == (2 * 256, 256)  # RGB and depth
    bad = httpx.get(f"{base}/frame.png", params={"part": "nope"}, timeout=60)
    assert bad.status_code == 400 and "part must be one of all, views, map" in bad.text


def test_the_pages_fit_a_phone(server: LocalServer, env: RemoteEnv, browser: Any) -> None:
    """At 390 px: the sessions list has a viewport (it had none: drawn at 980 px and shrunk) and
    the session page shows the map apart from the camera views, as wide as the screen allows."""
    env.reset(options={"episode_index": 0})
    env.step(int(Action.MOVE_FORWARD))
    page = browser.new_page(viewport={"width": 390, "height": 844}, device_scale_factor=2)
    try:
        page.goto(f"{server.url}/v1/live")
        assert page.locator('meta[name="viewport"]').count() == 1
        assert page.evaluate("document.documentElement.scrollWidth") <= 390
        assert page.evaluate("window.innerWidth") == 390  # laid out at the phone's width
        page.goto(f"{server.url}/v1/live/{env.session_id}")
        page.wait_for_function(
            "document.getElementById('map').complete && "
            "document.getElementById('map').naturalWidth > 0",
            timeout=10_000,
        )
        width = page.evaluate("document.getElementById('map').getBoundingClientRect().width")
        assert width >= 0.8 * 390, width  # the map alone across the screen, not a third of it
        assert page.evaluate("document.documentElement.scrollWidth") <= 390
        assert "path walked" in (page.get_attribute("#map", "alt") or "")
    finally:
        page.close()
