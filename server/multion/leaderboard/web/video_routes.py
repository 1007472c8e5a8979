"""``/leaderboard/runs/{id}/episodes/{position}.mp4`` and ``.vtt``: an episode's video and its
captions, served from the film cache with HEAD and byte ranges (a browser seeks by asking for
ranges: 206 Partial Content; a range outside the file: 416) and conditional requests: the ETag
and Last-Modified are those of the film's making, so ``If-None-Match`` or ``If-Modified-Since``
gets 304 Not Modified and a range with ``If-Range`` gets 206 while the film is unchanged.

A refusal is plain text naming the reason: 404 (no such run or episode, or one not played),
403 (an aggregate or sealed phase, a refunded run), 409 (the run has not ended), 422 (longer
than the video cap), 503 with ``Retry-After`` (being filmed now, or no PyAV on the server).
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Mapping
from email.utils import parsedate_to_datetime
from pathlib import Path

from fastapi import APIRouter, Request
from fastapi.responses import FileResponse, PlainTextResponse, Response
from sqlalchemy import func, select

from multion.leaderboard.models import EpisodeRecord, Run, utcnow
from multion.leaderboard.run_videos import Refusal, video_refusal
from multion.leaderboard.runs import RunService
from multion.leaderboard.web.videos import SAFE_RUN_ID, VideoFilmer

router = APIRouter(include_in_schema=False)
MEDIA_METHODS = ["GET", "HEAD"]
RETRY_AFTER_S = 10
CACHE_CONTROL = "public, max-age=3600"
MEDIA_TYPES = {"mp4": "video/mp4", "vtt": "text/vtt; charset=utf-8"}


def _refused(refusal: Refusal, headers: dict[str, str] | None = None) -> Response:
    return PlainTextResponse(refusal.message + "\n", refusal.status, headers=headers)


async def _film(request: Request, run_id: str, position: int, kind: str) -> Response:
    service: RunService = request.app.state.runs
    filmer: VideoFilmer | None = getattr(request.app.state, "videos", None)
    if not SAFE_RUN_ID.fullmatch(run_id):
        return _refused(Refusal(404, f"no run {run_id!r}"))

    def read() -> tuple[Run | None, EpisodeRecord | None, int]:
        with service.db.sessions() as session:
            run = session.get(Run, run_id)
            record = session.scalar(
                select(EpisodeRecord).where(
                    EpisodeRecord.run_id == run_id, EpisodeRecord.position == position
                )
            )
            count = session.scalar(select(func.count()).where(EpisodeRecord.run_id == run_id))
            return run, record, int(count or 0)

    run, record, episodes = await asyncio.to_thread(read)
    refusal = video_refusal(service.challenge, run, run_id, record, position, episodes, utcnow())
    if refusal is not None:
        return _refused(refusal)
    assert run is not None and record is not None
    if filmer is None:
        return _refused(
            Refusal(503, "videos are turned off on this server (multion serve --no-videos)")
        )
    if filmer.unavailable:
        return _refused(Refusal(503, filmer.unavailable))
    video, captions = filmer.cache.paths(run_id, position)
    if filmer.cache.ready(run_id, position):
        filmer.cache.watched(run_id, position)
        path = video if kind == "mp4" else captions
        try:
            stat = await asyncio.to_thread(os.stat, path)
        except FileNotFoundError:  # evicted this instant: filmed again below
            stat = None
        if stat is not None:
            return _served(request, path, stat, MEDIA_TYPES[kind])
    failed = filmer.failed.get((run_id, position))
    if failed is not None:
        return _refused(
            Refusal(500, f"episode {position} of run {run_id} could not be filmed: {failed}")
        )
    retry = {"Retry-After": str(RETRY_AFTER_S)}
    if not filmer.request(run, record):
        return _refused(Refusal(503, "too many videos are being made: try again later"), retry)
    message = f"episode {position} of run {run_id} is being filmed: try again in a few seconds"
    return _refused(Refusal(503, message), retry)


def _served(request: Request, path: Path, stat: os.stat_result, media_type: str) -> Response:
    """The file with validators of its filming (ETag, Last-Modified): 304 Not Modified to a
    request whose ``If-None-Match`` (or, without one, ``If-Modified-Since``) holds them; ranges
    (``If-Range`` too) are :class:`FileResponse`'s."""
    headers = {"Cache-Control": CACHE_CONTROL, "X-Content-Type-Options": "nosniff"}
    response = FileResponse(path, media_type=media_type, headers=headers, stat_result=stat)
    if not_modified(request.headers, response.headers["etag"], stat.st_mtime):
        for name in ("etag", "last-modified"):
            headers[name] = response.headers[name]
        return Response(status_code=304, headers=headers)
    return response


def not_modified(request: Mapping[str, str], etag: str, mtime: float) -> bool:
    """Whether a GET or HEAD with these headers is answered 304 (RFC 9110 13.1.2 and 13.1.3:
    If-None-Match by weak comparison; If-Modified-Since only without it)."""
    if_none_match = request.get("if-none-match")
    if if_none_match is not None:
        tags = [tag.strip().removeprefix("W/") for tag in if_none_match.split(",")]
        return "*" in tags or etag.removeprefix("W/") in tags
    if_modified_since = request.get("if-modified-since")
    if if_modified_since is None:
        return False
    try:
        since = parsedate_to_datetime(if_modified_since)
    except (TypeError, ValueError):  # not a date: ignored (RFC 9110 13.1.3)
        return False
    if since.tzinfo is None:
        return False
    return int(mtime) <= since.timestamp()


@router.api_route("/leaderboard/runs/{run_id}/episodes/{position}.mp4", methods=MEDIA_METHODS)
async def episode_video(run_id: str, position: int, request: Request) -> Response:
    """The H.264 MP4 of a played episode of a run on a phase with per-episode feedback."""
    return await _film(request, run_id, position, "mp4")


@router.api_route("/leaderboard/runs/{run_id}/episodes/{position}.vtt", methods=MEDIA_METHODS)
async def episode_captions(run_id: str, position: int, request: Request) -> Response:
    """The WebVTT captions of that video (each step's caption text)."""
    return await _film(request, run_id, position, "vtt")
