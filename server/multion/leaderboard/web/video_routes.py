"""``/leaderboard/runs/{id}/episodes/{position}.mp4`` and ``.vtt``: an episode's video and its
captions, served from the film cache with HEAD and byte ranges (a browser seeks by asking for
ranges: 206 Partial Content; a range outside the file: 416).

A refusal is plain text naming the reason: 404 (no such run or episode, or one not played),
403 (an aggregate or sealed phase, a refunded run), 409 (the run has not ended), 422 (longer
than the video cap), 503 with ``Retry-After`` (being filmed now, or no PyAV on the server).
"""

from __future__ import annotations

import asyncio
from typing import Any

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
        headers: dict[str, Any] = {
            "Cache-Control": CACHE_CONTROL,
            "X-Content-Type-Options": "nosniff",
        }
        return FileResponse(path, media_type=MEDIA_TYPES[kind], headers=headers)
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


@router.api_route("/leaderboard/runs/{run_id}/episodes/{position}.mp4", methods=MEDIA_METHODS)
async def episode_video(run_id: str, position: int, request: Request) -> Response:
    """The H.264 MP4 of a played episode of a run on a phase with per-episode feedback."""
    return await _film(request, run_id, position, "mp4")


@router.api_route("/leaderboard/runs/{run_id}/episodes/{position}.vtt", methods=MEDIA_METHODS)
async def episode_captions(run_id: str, position: int, request: Request) -> Response:
    """The WebVTT captions of that video (each step's caption text)."""
    return await _film(request, run_id, position, "vtt")
