"""The leaderboard's web pages (server-rendered with Jinja2; no build step, no external request).

``/`` and ``/leaderboard``: a table per track and phase; ``/leaderboard/runs/{id}``: a run;
``/leaderboard/teams/{name}``: a team's runs and its best score over time;
``/leaderboard/rules``: what each track allows. Styles and the small sorting script are served
from ``/leaderboard/static``; a Content-Security-Policy keeps every request on this server.
"""

from __future__ import annotations

import asyncio
import datetime as dt
from pathlib import Path
from typing import Any

from fastapi import APIRouter, FastAPI, Request
from fastapi.responses import HTMLResponse, Response
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates
from markupsafe import Markup
from sqlalchemy import select

from multion.leaderboard.challenge import Challenge
from multion.leaderboard.live_run import draw_of
from multion.leaderboard.models import EpisodePicture, EpisodeRecord, Run, Team, utcnow
from multion.leaderboard.runs import RunService
from multion.leaderboard.storage import Database
from multion.leaderboard.web import queries
from multion.leaderboard.web.charts import best_over_time
from multion.leaderboard.web.guide import render_guide, served_examples
from multion.leaderboard.web.pictures import (
    DISPLAY_SCALE,
    picture_png,
    pictured,
    stored_pictures,
)
from multion.leaderboard.web.video_routes import router as video_router
from multion.leaderboard.web.videos import VideoState, episode_summary
from multion_client.constants import GOAL_SETS

HERE = Path(__file__).resolve().parent
GUIDE = HERE.parents[3] / "docs" / "leaderboard.md"
"""The participants' guide, in a source checkout (server/multion/leaderboard/web → docs)."""
STATIC_PATH = "/leaderboard/static"
SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'none'; style-src 'self'; script-src 'self'; "
    "img-src 'self'; media-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}

templates = Jinja2Templates(directory=HERE / "templates")
router = APIRouter(include_in_schema=False)
PAGE_METHODS = ["GET", "HEAD"]
"""HTML pages answer HEAD too (uptime checkers use it); the server sends no body for it."""


def install_pages(app: FastAPI) -> None:
    """Add the pages and their static files to ``app``."""
    app.include_router(router)
    app.include_router(video_router)
    app.mount(STATIC_PATH, StaticFiles(directory=HERE / "static"), name="leaderboard-static")


def warm_pages(db: Database, challenge: Challenge) -> None:
    """Compile every page template and run the pages' queries once (on the newest run and its
    team), so that the first page view after a start costs what the next ones do: Jinja
    compiles a template at its first use (about 0.15 s of CPU for the run page's three) and
    SQLAlchemy each statement at its first execution, on a first database connection (0.6 s
    to 1.5 s for the first run page against 10-16 ms warm). Blocking: call it from a thread."""
    for name in templates.env.list_templates(extensions=["html"]):
        templates.env.get_template(name)
    now = utcnow()
    with db.sessions() as session:
        queries.leaderboards(session, challenge, now)
        newest = session.execute(
            select(Run.id, Team.name).join(Team).order_by(Run.created_at.desc()).limit(1)
        ).first()
        if newest is not None:
            queries.run_page(session, challenge, newest.id, now)
            stored_pictures(session, newest.id)
            queries.team_runs(session, challenge, newest.name, now)


def _percent(value: float | None) -> str:
    return "–" if value is None else f"{100 * value:.1f}"


def _date(value: dt.datetime | None) -> str:
    """Dates are stored and shown in UTC, and say so."""
    if value is None:
        return "–"
    if value.tzinfo is not None:
        value = value.astimezone(dt.timezone.utc)
    return f"{value:%Y-%m-%d %H:%M} UTC"


def _unbroken_date(value: dt.datetime | None) -> Markup:
    """A date in running text that never breaks across lines ("2999-01-01 / 00:00 UTC")."""
    return Markup('<span class="when">{}</span>').format(_date(value))


LONGEST_UNBROKEN = 24
"""A name's words up to this long never break inside (longer ones must, on a phone)."""


def _words(name: str) -> Markup:
    """A method or team name that breaks only between words: "random-oracle-found" and
    "2026-12-01" stay whole, where a browser would break after a hyphen or mid-word."""
    return Markup(" ").join(
        Markup('<span class="word">{}</span>').format(w) if len(w) <= LONGEST_UNBROKEN else w
        for w in name.split(" ")
    )


def _duration(seconds: float) -> str:
    """A time budget as people say it: "60 s", "90 minutes", "24 hours", "7 days"."""

    def unit(count: float, name: str) -> str:
        return f"{count:g} {name}{'' if count == 1 else 's'}"

    if seconds >= 3 * 86400 and seconds % 86400 == 0:
        return unit(seconds / 86400, "day")
    if seconds >= 3600 and seconds % 3600 == 0:
        return unit(seconds / 3600, "hour")
    if seconds >= 120 and seconds % 60 == 0:
        return unit(seconds / 60, "minute")
    return f"{seconds:g} s"


GOAL_SET_NAMES = {
    "colours": "8 coloured cylinders (" + ", ".join(GOAL_SETS["colours"]) + ")",
    "shapes": "8 red shapes on supports (" + ", ".join(GOAL_SETS["shapes"]).replace("_", " ") + ")",
    "objects": "8 everyday objects (" + ", ".join(GOAL_SETS["objects"]).replace("_", " ") + ")",
    "unseen_train": "8 random objects (pybullet_data random_urdfs 0-7)",
    "unseen_test": "8 random objects never seen in training (pybullet_data random_urdfs 500-507)",
}
"""How the rules page names each ``goal_set``."""

templates.env.filters["percent"] = _percent
templates.env.filters["duration"] = _duration
templates.env.filters["date"] = _date
templates.env.filters["unbroken_date"] = _unbroken_date
templates.env.filters["words"] = _words
templates.env.globals["metric_names"] = queries.METRIC_NAMES
templates.env.globals["goal_set_names"] = GOAL_SET_NAMES
templates.env.globals["static"] = STATIC_PATH


def _service(request: Request) -> RunService:
    service: RunService = request.app.state.runs
    return service


def _page(request: Request, name: str, status: int = 200, **context: Any) -> HTMLResponse:
    context["challenge"] = _service(request).challenge
    response = templates.TemplateResponse(request, name, context, status_code=status)
    response.headers.update(SECURITY_HEADERS)
    return response


def _not_found(request: Request, what: str) -> HTMLResponse:
    return _page(request, "not_found.html", status=404, what=what)


async def _read(request: Request, work: Any) -> Any:
    """Run ``work(session)`` in a thread (database reads block)."""
    service = _service(request)

    def read() -> Any:
        with service.db.sessions() as session:
            return work(session)

    return await asyncio.to_thread(read)


@router.api_route("/", methods=PAGE_METHODS, response_class=HTMLResponse)
@router.api_route("/leaderboard", methods=PAGE_METHODS, response_class=HTMLResponse)
async def leaderboard(request: Request) -> HTMLResponse:
    challenge = _service(request).challenge
    boards = await _read(request, lambda s: queries.leaderboards(s, challenge, utcnow()))
    return _page(request, "leaderboard.html", boards=boards)


@router.api_route("/leaderboard/rules", methods=PAGE_METHODS, response_class=HTMLResponse)
async def rules(request: Request) -> HTMLResponse:
    docs_url = getattr(request.app.state, "docs_url", None)
    if docs_url is None and GUIDE.is_file():
        docs_url = "/leaderboard/guide"
    server_url = str(request.base_url).rstrip("/")
    return _page(request, "rules.html", docs_url=docs_url, server_url=server_url)


@router.api_route("/leaderboard/guide", methods=PAGE_METHODS, response_class=HTMLResponse)
async def guide(request: Request) -> HTMLResponse:
    """The participant parts of docs/leaderboard.md, rendered (its examples on this server and
    its first track), where the server runs from a source tree; elsewhere the organisers set
    MULTION_LEADERBOARD_DOCS_URL."""
    if not GUIDE.is_file():
        return _not_found(request, "copy of the guide on this server")
    served = served_examples(_service(request).challenge, str(request.base_url))
    html = render_guide(GUIDE.read_text(encoding="utf-8"), served)
    return _page(request, "guide.html", html=html)


@router.api_route("/leaderboard/runs/{run_id}", methods=PAGE_METHODS, response_class=HTMLResponse)
async def run_page(run_id: str, request: Request) -> HTMLResponse:
    service = _service(request)

    def read(session: Any) -> tuple[queries.RunPage | None, dict[int, EpisodePicture]]:
        page = queries.run_page(session, service.challenge, run_id, utcnow())
        drawn = stored_pictures(session, run_id) if page is not None and page.per_episode else {}
        return page, drawn

    page, drawn = await _read(request, read)
    if page is None:
        return _not_found(request, f"run {run_id}")
    houses: list[queries.Breakdown] = []
    pictures: list[tuple[EpisodeRecord, EpisodePicture | None]] = []
    if page.per_episode and page.track is not None and page.phase is not None:
        labels = await asyncio.to_thread(_house_labels, service, page)
        houses = queries.breakdown(page.records, labels)
        pictures = [(r, drawn.get(r.position)) for r in pictured(page.records)]
    return _page(
        request, "run.html", page=page, houses=houses, pictures=pictures, scale=DISPLAY_SCALE,
        videos=_videos(request, page), summary=episode_summary,
    )  # fmt: skip


def _videos(request: Request, page: queries.RunPage) -> list[VideoState]:
    """The videos the run page shows: of the pictured episodes, where the phase gives
    per-episode feedback (nothing is filmed here: the background films them)."""
    filmer = getattr(request.app.state, "videos", None)
    if filmer is None or not page.per_episode:
        return []
    return [filmer.state(page.run.id, record) for record in pictured(page.records)]


@router.api_route("/leaderboard/runs/{run_id}/episodes/{position}.png", methods=PAGE_METHODS)
async def episode_picture(run_id: str, position: int, request: Request) -> Response:
    """A stored picture of one of a run's first episodes (drawn when the run ended; nothing is
    drawn here, so a burst of requests costs only database reads)."""
    service = _service(request)

    def read(session: Any) -> bytes | None:
        return picture_png(session, service.challenge, run_id, position, utcnow())

    png = await _read(request, read)
    if png is None:
        return _not_found(request, f"a picture of episode {position} of run {run_id}")
    headers = {**SECURITY_HEADERS, "Cache-Control": "public, max-age=86400"}
    return Response(png, media_type="image/png", headers=headers)


@router.api_route("/leaderboard/teams/{team}", methods=PAGE_METHODS, response_class=HTMLResponse)
async def team_page(team: str, request: Request) -> HTMLResponse:
    challenge = _service(request).challenge
    runs = await _read(request, lambda s: queries.team_runs(s, challenge, team, utcnow()))
    if runs is None:
        return _not_found(request, f"team {team}")
    charts = []
    for track in challenge.tracks:
        svg = best_over_time(
            [r for r in runs if r.track == track.name],
            queries.METRIC_NAMES[track.metric],
            track.name,
        )
        if svg:
            charts.append((track, svg))
    return _page(request, "team.html", team=team, runs=runs, charts=charts)


def _house_labels(service: RunService, page: queries.RunPage) -> dict[int, str]:
    """The run's episode indices → "house N", numbered in the phase's house order (the house
    ids themselves stay secret). Blocking: call it from a thread."""
    assert page.track is not None and page.phase is not None
    draw = draw_of(page.run)
    houses = service.hidden.house_of(page.track, page.phase, draw)
    return {index: f"house {houses[p] + 1}" for p, index in enumerate(draw.order)}
