"""Turning the leaderboard on in a server: the challenge, the database and the run service.

``create_app(settings, [LeaderboardExtension(leaderboard)])`` calls :func:`check_leaderboard`
when it builds the app (so a bad challenge file or database fails at once) and
:func:`leaderboard_lifespan` inside its lifespan, once the session registry exists.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator
from dataclasses import dataclass

from fastapi import FastAPI

from multion.api.sessions import SessionRegistry
from multion.api.workers import WorkerReport
from multion.config.sim import EGL_PACKAGES
from multion.leaderboard.challenge import Challenge, ChallengeError
from multion.leaderboard.challenge_file import load_challenge
from multion.leaderboard.clock import Clock
from multion.leaderboard.live_run import draw_of
from multion.leaderboard.models import utcnow
from multion.leaderboard.routes import TokenCache, router, team_of
from multion.leaderboard.runs import RunService
from multion.leaderboard.settings import LeaderboardSettings
from multion.leaderboard.storage import Database, check_secret
from multion.leaderboard.web.pages import install_pages, warm_pages
from multion.leaderboard.web.pictures import PictureDrawer
from multion.leaderboard.web.videos import VideoCache, VideoFilmer, default_video_dir

log = logging.getLogger("multion.leaderboard")


def check_leaderboard(app: FastAPI, settings: LeaderboardSettings) -> Challenge:
    """Read the challenge (ChallengeError on a bad file), open (create or upgrade) the database
    and check it was used with the same secret (StorageError if not), and add the routes and
    web pages."""
    challenge = load_challenge(settings.challenge)
    for warning in challenge.warnings(utcnow()):
        log.warning("%s: %s", settings.challenge, warning)
    db = Database.open(settings.database)
    try:
        with db.sessions.begin() as session:
            check_secret(session, challenge.secret)
    finally:
        db.close()
    app.include_router(router)
    install_pages(app)
    return challenge


@contextlib.asynccontextmanager
async def leaderboard_lifespan(
    app: FastAPI,
    settings: LeaderboardSettings,
    challenge: Challenge,
    registry: SessionRegistry,
    clock: Clock | None = None,
) -> AsyncIterator[None]:
    """Check the tracks' renderers open in the workers (ChallengeError if not), open (and
    migrate) the database, start the run service and its expiry loop; the service's deadlines
    follow ``clock`` (None: the wall clock)."""
    problem = renderer_problem(challenge, await registry.pool.report())
    if problem is not None:
        raise ChallengeError(problem)
    db = await asyncio.to_thread(Database.open, settings.database)
    service = RunService(challenge, db, registry, clock)
    app.state.runs, app.state.token_cache = service, TokenCache(settings.token_cache_s)
    app.state.authenticate = team_of  # for plain sessions on a `--sessions token` server
    registry.run_reserve = app.state.settings.run_reserve
    app.state.docs_url = settings.docs_url
    pictures = PictureDrawer(
        challenge, db, lambda t, p, run, r: service.hidden.episode(t, p, draw_of(run), r.position)
    )
    tasks = [asyncio.create_task(service.expire_forever(settings.expire_interval_s))]
    if settings.draw_pictures:
        tasks.append(asyncio.create_task(pictures.draw_forever(settings.picture_interval_s)))
    app.state.videos = None
    if settings.videos:
        app.state.videos = videos = _filmer(settings, challenge, db, service, pictures)
        if settings.draw_pictures:  # films of the pictured episodes, in the background
            tasks.append(asyncio.create_task(videos.film_forever(settings.picture_interval_s)))
    if settings.warm_up:
        tasks.append(asyncio.create_task(_warm_up(service)))
        try:  # before the first request: it would compile them
            await asyncio.to_thread(warm_pages, db, challenge)
        except Exception:  # noqa: BLE001 - reported; the first page view does it
            log.exception("preparing the web pages failed")
    try:
        yield
    finally:
        for task in tasks:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        await service.close()
        pictures.close()
        db.close()


def renderer_problem(challenge: Challenge, report: WorkerReport | None) -> str | None:
    """Why the tracks that render with ``gl`` cannot be served by these workers (they could
    not open an OpenGL context), or None: said when the server starts, not to the first
    participant whose run would fail."""
    tracks = [t.name for t in challenge.tracks if t.camera.get("renderer") == "gl"]
    if not tracks or report is None or report.gl_unavailable is None:
        return None
    return (
        f"track(s) {', '.join(tracks)} render with camera.renderer = 'gl', which does not open "
        f"in this server's simulator workers: {report.gl_unavailable}. Install Mesa's EGL "
        f"(apt-get install {EGL_PACKAGES}) or a GPU driver, or set the tracks' renderer to "
        "'tiny'"
    )


@dataclass
class LeaderboardExtension:
    """The leaderboard as an extension of the session server:
    ``create_app(settings, [LeaderboardExtension(leaderboard_settings)])``."""

    settings: LeaderboardSettings
    clock: Clock | None = None
    """What the runs' deadlines follow (None: the wall clock; tests pass a ManualClock)."""
    authenticates_teams: bool = True
    challenge: Challenge | None = None
    """Read by :meth:`install`, when the app is built."""

    def install(self, app: FastAPI) -> None:
        self.challenge = check_leaderboard(app, self.settings)

    def lifespan(
        self, app: FastAPI, registry: SessionRegistry
    ) -> contextlib.AbstractAsyncContextManager[None]:
        assert self.challenge is not None, "install() runs first, when the app is built"
        return leaderboard_lifespan(app, self.settings, self.challenge, registry, self.clock)


def _filmer(
    settings: LeaderboardSettings, challenge: Challenge, db: Database, service: RunService,
    pictures: PictureDrawer,
) -> VideoFilmer:  # fmt: skip
    directory = settings.video_dir or default_video_dir(settings.database)
    cache = VideoCache(directory, settings.video_cache_mib * 2**20)
    return VideoFilmer(
        challenge, db, cache,
        lambda t, p, run, r: service.hidden.episode(t, p, draw_of(run), r.position),
        pictures.in_helper,
    )  # fmt: skip


async def _warm_up(service: RunService) -> None:
    """Generate every phase's fixed episodes and build its houses now, so the first run does
    not wait for them."""
    for track in service.challenge.tracks:
        for phase in track.phases:
            try:
                await asyncio.to_thread(service.hidden.warm, track, phase)
            except Exception:  # noqa: BLE001 - reported; the first run will try again
                log.exception(
                    "generating the hidden episodes of %s/%s failed", track.name, phase.name
                )
