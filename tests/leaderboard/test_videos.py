"""Issue 46 item 2: the run pages' episode videos. Filmed in the background by the picture
drawer's process, cached on disk, served with HEAD and byte ranges, with a WebVTT caption track
and a text account beside each; never on aggregate or sealed phases; the organiser's
``multion leaderboard replay RUN --video DIR`` films any run.

Needs PyAV (``pip install -e '.[video]'``); without it these tests skip, unless
``MULTION_REQUIRE_VIDEO=1`` (set by .ci/run) makes them required."""

from __future__ import annotations

import datetime as dt
import io
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from played_runs import PlayedRun

from multion.leaderboard.challenge import Challenge
from multion.leaderboard.models import EpisodeRecord, Run
from multion.leaderboard.run_videos import video_refusal
from multion.leaderboard.storage import Database
from multion.video.stored import END_HOLD, MAX_VIDEO_FRAMES, frame_count
from multion_agents.cli import main
from waiting import wait_until

VIDEO_HINT = (
    "needs PyAV: pip install -e '.[video]'; MULTION_REQUIRE_VIDEO=1 (set by .ci/run) makes "
    "these tests required"
)
try:
    import av
except ImportError:
    if os.environ.get("MULTION_REQUIRE_VIDEO") == "1":
        raise
    pytest.skip(VIDEO_HINT, allow_module_level=True)

FILMED_WITHIN_S = 240.0


@pytest.fixture(scope="module")
def video_dir(workdir: Path) -> Path:
    return workdir / "videos"


@pytest.fixture(scope="module")
def server(
    challenge_file: Path, database: str, video_dir: Path, launch: Callable[..., Any]
) -> Iterator[Any]:
    """The module's server keeps its films in ``video_dir``."""
    server = launch(challenge_file, database, {"MULTION_LEADERBOARD_VIDEO_DIR": str(video_dir)})
    try:
        yield server
    finally:
        server.stop()


def _url(server: Any, run_id: str, position: int, kind: str = "mp4") -> str:
    return f"{server.url}/leaderboard/runs/{run_id}/episodes/{position}.{kind}"


def filmed_page(server: Any, run_id: str) -> str:
    """The run page once the background has filmed its episodes."""

    def page_once_filmed() -> str | None:
        page = httpx.get(f"{server.url}/leaderboard/runs/{run_id}", timeout=60).text
        return None if "being made" in page or "<video" not in page else page

    return wait_until(page_once_filmed, timeout=FILMED_WITHIN_S, interval=0.5,
                      message="the run's videos to be filmed")  # fmt: skip


def _records(database: str, run_id: str) -> list[EpisodeRecord]:
    db = Database.open(database)
    try:
        with db.sessions() as session:
            run = session.get(Run, run_id)
            assert run is not None
            return sorted(run.episodes, key=lambda r: r.position)
    finally:
        db.close()


def test_the_run_page_shows_each_video_with_captions_and_a_text_account(
    server: Any, played: dict[str, PlayedRun], database: str
) -> None:
    run_id = played["beta"].run_id
    page = filmed_page(server, run_id)
    records = _records(database, run_id)
    for record in records:  # the minival run's 3 episodes, all played
        assert f'src="/leaderboard/runs/{run_id}/episodes/{record.position}.mp4"' in page
        assert (
            f'<track kind="captions" srclang="en" label="Steps" src="/leaderboard/runs/{run_id}/episodes/{record.position}.vtt">'
            in page
        )
        account = f"Episode {record.position + 1}: {len(record.actions)} steps, ended by {record.end_reason}"
        assert account in page
        assert f'aria-describedby="video-summary-{record.position}"' in page
    answer = httpx.get(f"{server.url}/leaderboard/runs/{run_id}", timeout=60)
    assert "media-src 'self'" in answer.headers["content-security-policy"]

    video = httpx.get(_url(server, run_id, 0), timeout=60)
    assert video.status_code == 200 and video.headers["content-type"] == "video/mp4"
    assert video.headers["accept-ranges"] == "bytes"
    with av.open(io.BytesIO(video.content)) as container:
        frames = sum(1 for _ in container.decode(video=0))
    assert frames == frame_count([int(a) for a in records[0].actions])
    captions = httpx.get(_url(server, run_id, 0, "vtt"), timeout=60)
    assert captions.status_code == 200 and captions.headers["content-type"].startswith("text/vtt")
    assert captions.text.startswith("WEBVTT\n\n1\n00:00:00.000 --> 00:00:00.100\n")
    assert "step 0/40" in captions.text and f"step {len(records[0].actions)}/40" in captions.text
    # the hidden episode and house ids stay secret: the title names the method and the number
    assert "beta explorer · 1-on minival · episode 1" in captions.text
    assert records[0].episode_id not in captions.text


def test_videos_answer_head_and_byte_ranges(server: Any, played: dict[str, PlayedRun]) -> None:
    run_id = played["beta"].run_id
    filmed_page(server, run_id)
    url = _url(server, run_id, 1)
    size = len(httpx.get(url, timeout=60).content)
    head = httpx.head(url, timeout=60)
    assert head.status_code == 200 and head.content == b""
    assert int(head.headers["content-length"]) == size
    part = httpx.get(url, headers={"Range": "bytes=100-199"}, timeout=60)
    assert part.status_code == 206 and len(part.content) == 100
    assert part.headers["content-range"] == f"bytes 100-199/{size}"
    whole = httpx.get(url, timeout=60).content
    assert part.content == whole[100:200]
    tail = httpx.get(url, headers={"Range": "bytes=-10"}, timeout=60)
    assert tail.status_code == 206 and tail.content == whole[-10:]
    outside = httpx.get(url, headers={"Range": f"bytes={size + 10}-{size + 20}"}, timeout=60)
    assert outside.status_code == 416 and outside.headers["content-range"] == f"bytes */{size}"


def test_videos_keep_their_validators_for_conditional_and_range_requests(
    server: Any, played: dict[str, PlayedRun]
) -> None:
    """Issue 53 item 1: watching a film (which marks it for the cache's eviction order) left its
    ETag and Last-Modified changed, so no request got 304 and If-Range got the whole film."""
    run_id = played["beta"].run_id
    filmed_page(server, run_id)
    for kind in ("mp4", "vtt"):
        url = _url(server, run_id, 2, kind)
        first, second = httpx.get(url, timeout=60), httpx.head(url, timeout=60)
        etag, modified = first.headers["etag"], first.headers["last-modified"]
        assert (second.headers["etag"], second.headers["last-modified"]) == (etag, modified)
        for conditional in ({"If-None-Match": etag}, {"If-None-Match": f'"other", W/{etag}'},
                            {"If-None-Match": "*"}, {"If-Modified-Since": modified}):  # fmt: skip
            for answer in (httpx.get(url, headers=conditional, timeout=60),
                           httpx.head(url, headers=conditional, timeout=60)):  # fmt: skip
                assert answer.status_code == 304, (kind, conditional)
                assert answer.content == b"" and answer.headers["etag"] == etag
                assert answer.headers["cache-control"] == "public, max-age=3600"
        assert httpx.get(url, headers={"If-None-Match": '"other"'}, timeout=60).status_code == 200
        old = "Mon, 01 Jan 2001 00:00:00 GMT"
        assert httpx.get(url, headers={"If-Modified-Since": old}, timeout=60).status_code == 200
        for validator in (etag, modified):
            part = httpx.get(url, headers={"Range": "bytes=5-14", "If-Range": validator},
                             timeout=60)  # fmt: skip
            assert part.status_code == 206 and part.content == first.content[5:15]
        whole = httpx.get(url, headers={"Range": "bytes=5-14", "If-Range": '"other"'}, timeout=60)
        assert whole.status_code == 200 and whole.content == first.content


def test_a_cached_video_is_not_filmed_again_and_an_evicted_one_is(
    server: Any, played: dict[str, PlayedRun], video_dir: Path, tmp_path: Path
) -> None:
    run_id = played["alpha-1"].run_id
    filmed_page(server, run_id)
    film = video_dir / run_id / "episode-0-v1.mp4"
    first = film.stat().st_ino
    for _ in range(3):
        assert httpx.get(_url(server, run_id, 0), timeout=60).status_code == 200
    assert film.stat().st_ino == first  # served from the cache, never filmed again
    os.link(film, tmp_path / "kept.mp4")  # keeps the inode taken: a new film gets another
    film.unlink()  # evicted: the next request films it again, meanwhile "try again shortly"
    answer = httpx.get(_url(server, run_id, 0), timeout=60)
    assert answer.status_code == 503 and answer.headers["retry-after"] == "10"
    assert "is being filmed" in answer.text
    wait_until(lambda: httpx.head(_url(server, run_id, 0), timeout=60).status_code == 200,
               timeout=FILMED_WITHIN_S, interval=0.5, message="the video to be filmed again")  # fmt: skip
    assert film.stat().st_ino != first


def test_bad_video_requests_get_clear_4xx(server: Any, played: dict[str, PlayedRun]) -> None:
    beta = played["beta"].run_id

    def refused(url: str, status: int, text: str) -> None:
        for answer in (httpx.get(url, timeout=60), httpx.head(url, timeout=60)):
            assert answer.status_code == status, (url, answer.text)
        assert text in httpx.get(url, timeout=60).text

    refused(_url(server, "nope", 0), 404, "no run 'nope'")
    refused(_url(server, beta, 3), 404, f"run {beta} has no episode 3 (it has positions 0 to 2)")
    refused(_url(server, beta, -1, "vtt"), 404, "has no episode -1")
    standard = played["standard"].run_id
    refused(_url(server, standard, 0), 403, "phase 1-on/test-standard shows aggregate results only")
    sealed = played["sealed"].run_id
    refused(
        _url(server, sealed, 0, "vtt"),
        403,
        "phase 1-on-oracle/test-challenge is sealed until 2999-01-01",
    )
    assert (
        httpx.get(_url(server, beta, 0).replace("/0.mp4", "/first.mp4"), timeout=60).status_code
        == 422
    )
    for label in ("standard", "sealed"):
        page = httpx.get(f"{server.url}/leaderboard/runs/{played[label].run_id}", timeout=60).text
        assert "<video" not in page and ".mp4" not in page


def test_refusals_of_unplayed_unended_and_too_long_episodes(challenge: Challenge) -> None:
    now = dt.datetime.now(dt.timezone.utc)
    run = Run(id="r1", track="1-on", phase="minival", summary={"episodes": 1}, refunded=False)
    record = EpisodeRecord(position=0, actions="2" * 10, end_reason="max_steps", metrics={})
    assert video_refusal(challenge, run, "r1", record, 0, 1, now) is None
    long = EpisodeRecord(position=0, actions="2" * (MAX_VIDEO_FRAMES - END_HOLD), metrics={})
    refusal = video_refusal(challenge, run, "r1", long, 0, 1, now)
    assert refusal is not None and refusal.status == 422
    assert f"{MAX_VIDEO_FRAMES + 1} frames" in refusal.message and "10 minutes" in refusal.message
    unplayed = EpisodeRecord(position=0, actions="", metrics={})
    refusal = video_refusal(challenge, run, "r1", unplayed, 0, 1, now)
    assert refusal is not None and refusal.status == 404 and "was not played" in refusal.message
    running = Run(id="r2", track="1-on", phase="minival", summary=None, refunded=False)
    refusal = video_refusal(challenge, running, "r2", record, 0, 1, now)
    assert refusal is not None and refusal.status == 409 and "has not ended" in refusal.message
    refunded = Run(id="r3", track="1-on", phase="minival", summary={}, refunded=True)
    refusal = video_refusal(challenge, refunded, "r3", record, 0, 1, now)
    assert refusal is not None and refusal.status == 403 and "refunded" in refusal.message


def test_a_server_without_pyav_says_what_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    from multion.leaderboard.web.videos import encoder_missing

    assert encoder_missing() == ""
    monkeypatch.setitem(sys.modules, "av", None)  # import av now raises ImportError
    message = encoder_missing()
    assert "Videos are off on this server" in message and "pip install -e '.[video]'" in message


def test_the_organiser_films_any_run(
    server: Any,
    played: dict[str, PlayedRun],
    database: str,
    challenge_file: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    sealed = played["sealed"].run_id  # sealed until 2999: no participant sees its episodes
    flags = ["--database", database, "--challenge", str(challenge_file)]
    code = main(
        ["leaderboard", "replay", sealed, *flags, "--video", str(tmp_path), "--episode", "2"]
    )
    out, err = capsys.readouterr()
    assert code == 0, err
    film = tmp_path / f"{sealed}-episode-2.mp4"
    assert f"wrote {film} (" in out and (tmp_path / f"{sealed}-episode-2.vtt").is_file()
    record = _records(database, sealed)[1]
    with av.open(str(film)) as container:
        assert sum(1 for _ in container.decode(video=0)) == frame_count(
            [int(a) for a in record.actions]
        )
    assert not list(tmp_path.glob("*-episode-1.*"))

    def error(*argv: str) -> str:
        assert main(["leaderboard", "replay", sealed, *flags, *argv]) == 2
        return capsys.readouterr().err

    assert f"--episode 3: run {sealed} has episodes 1 to 2" in error(
        "--video", str(tmp_path), "--episode", "3"
    )
    assert "a file, not a folder" in error("--video", str(film))
    assert "--episode goes with --video DIR" in error("--episode", "1")
    assert main(["leaderboard", "replay", "nope", *flags, "--video", str(tmp_path)]) == 2
    assert "no run 'nope'" in capsys.readouterr().err


def test_the_cache_removes_the_least_recently_watched_films_first(tmp_path: Path) -> None:
    from multion.leaderboard.web.videos import VideoCache

    cache = VideoCache(tmp_path, max_bytes=2500)
    for position in range(3):  # 3 films of 1,000 bytes (with captions): one too many
        video, captions = cache.paths("run1", position)
        video.parent.mkdir(exist_ok=True)
        video.write_bytes(b"v" * 900)
        captions.write_bytes(b"c" * 100)
        os.utime(video, (1000 + position, 1000 + position))
    before = [path.stat().st_mtime for path in cache.paths("run1", 0)]
    cache.watched("run1", 0)  # watched now: the last to go
    # its validators (ETag, Last-Modified: from the mtime) stay those of its filming (issue 53)
    assert [path.stat().st_mtime for path in cache.paths("run1", 0)] == before
    assert cache.evict() == 1
    assert [cache.ready("run1", p) for p in range(3)] == [True, False, True]
    assert not list(tmp_path.glob("run1/episode-1-*"))  # its film, captions and mark
    assert cache.evict() == 0
    with pytest.raises(ValueError, match="not a run id"):
        cache.paths("../etc", 0)
