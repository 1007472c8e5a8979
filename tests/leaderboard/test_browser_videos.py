"""Issue 46 item 2 in a real headless Chromium: a run page's video loads, seeks (the browser
asks for byte ranges: 206), and its caption track and text account are there. Skips without
Chromium / Playwright (``MULTION_REQUIRE_BROWSER=1`` requires them) or PyAV (see
test_videos)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from played_runs import PlayedRun
from test_browser import browser, visit  # noqa: F401, F811 - the fixtures
from test_videos import filmed_page

pytest.importorskip("av", reason="needs PyAV: pip install -e '.[video]'")


@pytest.fixture(scope="module")
def server(
    challenge_file: Path, database: str, workdir: Path, launch: Callable[..., Any]
) -> Iterator[Any]:
    server = launch(
        challenge_file, database, {"MULTION_LEADERBOARD_VIDEO_DIR": str(workdir / "videos")}
    )
    try:
        yield server
    finally:
        server.stop()


def test_a_run_video_plays_seeks_and_has_captions(
    visit: Any,  # noqa: F811 - the fixture imported above
    server: Any,
    played: dict[str, PlayedRun],
) -> None:
    run_id = played["beta"].run_id
    filmed_page(server, run_id)
    v = visit()
    answers: list[tuple[str, int]] = []
    v.page.on("response", lambda r: answers.append((r.url, r.status)))
    page = v.goto(f"/leaderboard/runs/{run_id}")
    video = page.locator(".videos video").first
    video.scroll_into_view_if_needed()
    page.wait_for_function(
        "() => document.querySelector('.videos video').readyState >= 1", timeout=60_000
    )
    duration = video.evaluate("v => v.duration")
    assert duration > 2  # 10 frames a second, at least the 2 s held at the end
    seeked = video.evaluate(
        """v => new Promise(done => {
            v.addEventListener('seeked', () => done(v.currentTime), {once: true});
            v.currentTime = v.duration / 2;
        })"""
    )
    assert abs(seeked - duration / 2) < 0.2
    page.wait_for_function(
        "() => document.querySelector('.videos video').readyState >= 2", timeout=60_000
    )
    v.shot("run-with-videos")
    mp4 = [status for url, status in answers if url.endswith("/episodes/0.mp4")]
    assert 206 in mp4, answers  # the browser fetched byte ranges
    # the caption track: shown, its cues loaded, the one at the middle names a step
    cue = video.evaluate(
        """v => new Promise(done => {
            const track = v.textTracks[0];
            track.mode = 'showing';
            const read = () => track.cues && track.cues.length
                ? done([track.kind, track.cues.length, track.activeCues.length
                    ? track.activeCues[0].text : track.cues[0].text])
                : setTimeout(read, 100);
            read();
        })"""
    )
    assert cue[0] == "captions" and cue[1] > 1 and "step " in cue[2]
    account = page.locator("#video-summary-0").inner_text()
    assert account.startswith("Episode 1: ") and "ended by" in account
