"""The live view of a session: a page that shows what the agent sees as it steps.

``GET /v1/live/{session_id}`` is a small page that polls ``…/state`` (episode, step, last
action, metrics; JSON) and reloads ``…/frame.png`` (RGB, depth, map) whenever the step changes.
It is for a researcher debugging an agent against a server on their own machine, so it answers
only when the server's ``live_view`` setting is on (by default only for a server listening on a
loopback address), only to requests from this machine that no proxy forwarded, and never for a
leaderboard run's session (its episodes are hidden).
"""

from __future__ import annotations

import html
import ipaddress
import json

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, JSONResponse, Response

from multion.api.live_view import PARTS, latest_step, picture
from multion.api.sessions import Session, SessionRegistry
from multion.api.settings import ServerSettings

LIVE_PATH = "/v1/live"
POLL_MS = 250
FORWARDED_HEADERS = ("forwarded", "x-forwarded-for", "x-real-ip")

router = APIRouter(prefix=LIVE_PATH, tags=["live view"], include_in_schema=False)


class Refused(Exception):
    """A request the live view does not answer: its status, code and message."""

    def __init__(self, status: int, code: str, message: str) -> None:
        super().__init__(message)
        self.status, self.code, self.message = status, code, message


def _check_viewer(request: Request) -> None:
    """Refuse requests the live view does not answer (off, or not from this machine)."""
    settings: ServerSettings = request.app.state.settings
    if not settings.live_view_on():
        raise Refused(
            403, "live_view_off",
            "the live view is off on this server: start it with `multion serve --live-view "
            "local` (with the default, auto, it is on only when --host is a loopback address)",
        )  # fmt: skip
    host = request.client.host if request.client is not None else ""
    forwarded = [name for name in FORWARDED_HEADERS if name in request.headers]
    if not _is_loopback(host) or forwarded:
        raise Refused(
            403, "live_view_local_only",
            "the live view answers only requests from the server's own machine"
            + (f" (this one was forwarded: {', '.join(forwarded)})" if forwarded else ""),
        )  # fmt: skip


def _viewed(request: Request, session_id: str, env: int) -> Session:
    """The session to show, after checking that this request may see it."""
    _check_viewer(request)
    registry: SessionRegistry = request.app.state.registry
    session = registry.sessions.get(session_id)
    if session is None:
        raise Refused(404, "session_not_found", f"no session {session_id!r} on this server")
    if session.owner is None:
        raise Refused(403, "live_view_not_for_runs", "leaderboard runs have no live view")
    if not 0 <= env < session.num_envs:
        raise Refused(400, "bad_request", f"env must be in [0, {session.num_envs - 1}], got {env}")
    return session


def _is_loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _json_refusal(refused: Refused) -> JSONResponse:
    body = {"error": {"code": refused.code, "message": refused.message}}
    return JSONResponse(body, status_code=refused.status)


@router.get("")
async def sessions(request: Request) -> Response:
    """The sessions this server holds that the live view shows, each a link to its page."""
    try:
        _check_viewer(request)
    except Refused as refused:
        text = f"<!doctype html><title>Live view refused</title><p>{html.escape(refused.message)}"
        return HTMLResponse(text, status_code=refused.status)
    registry: SessionRegistry = request.app.state.registry
    items = "".join(
        f'<li><a href="{LIVE_PATH}/{html.escape(s.session_id)}?env={env}">'
        f"{html.escape(s.session_id)}, environment {env}</a></li>"
        for s in registry.sessions.values()
        if s.owner is not None and s.failed is None
        for env in range(s.num_envs)
    )
    body = f"<ul>{items}</ul>" if items else "<p>No session is open on this server now.</p>"
    text = (
        '<!doctype html><html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>Live view: sessions</title><style>{LIST_STYLE}</style></head>"
        f"<body><h1>Sessions</h1>{body}</body></html>"
    )
    return HTMLResponse(text, headers={"Cache-Control": "no-store"})


@router.get("/{session_id}/state")
async def state(session_id: str, request: Request, env: int = 0) -> Response:
    try:
        step = latest_step(_viewed(request, session_id, env), env)
    except Refused as refused:
        return _json_refusal(refused)
    body = {"started": False} if step is None else step.state()
    return JSONResponse(body, headers={"Cache-Control": "no-store"})


@router.get("/{session_id}/frame.png")
async def frame(session_id: str, request: Request, env: int = 0, part: str = "all") -> Response:
    """The picture: every panel (``part=all``), the camera views or the map."""
    try:
        session = _viewed(request, session_id, env)
        if part not in PARTS:
            raise Refused(
                400, "bad_request", f"part must be one of {', '.join(PARTS)}, got {part!r}"
            )
    except Refused as refused:
        return _json_refusal(refused)
    step = latest_step(session, env)
    if step is None:
        return _json_refusal(Refused(409, "not_reset", "no episode has started in this session"))
    return Response(picture(session, step, part), media_type="image/png",
                    headers={"Cache-Control": "no-store"})  # fmt: skip


@router.get("/{session_id}")
async def page(session_id: str, request: Request, env: int = 0) -> Response:
    try:
        _viewed(request, session_id, env)
    except Refused as refused:
        text = f"<!doctype html><title>Live view refused</title><p>{html.escape(refused.message)}"
        return HTMLResponse(text, status_code=refused.status)
    base = f"{LIVE_PATH}/{session_id}"
    page_text = PAGE.replace("{{TITLE}}", html.escape(f"{session_id}, environment {env}"))
    page_text = page_text.replace(
        "{{CONFIG}}", json.dumps({"base": base, "env": env, "poll": POLL_MS})
    )
    return HTMLResponse(page_text, headers={"Cache-Control": "no-store"})


LIST_STYLE = (
    "body { font-family: system-ui, sans-serif; margin: 1rem; color: #1a1a1a; } "
    "li { margin: .6rem 0; overflow-wrap: anywhere; } a { padding: .2rem 0; }"
)
"""The sessions list: ids wrap rather than run off a phone's screen; links are easy to tap."""

PAGE = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>Live view: session {{TITLE}}</title>
<style>
  body { font-family: system-ui, sans-serif; margin: 1rem; color: #1a1a1a; }
  .pictures { display: flex; flex-wrap: wrap; gap: .5rem; align-items: flex-start; }
  img { max-width: 100%; image-rendering: pixelated; border: 1px solid #ccc; min-height: 2rem; }
  dl { display: grid; grid-template-columns: max-content max-content; gap: .15rem 1rem; }
  dt { font-weight: 600; }
</style>
</head>
<body>
<h1>Live view</h1>
<p>Session {{TITLE}}. The pictures: what the agent sees (RGB, depth, as far as the session asked
for them) and the house from above, with the goals in order (the current one ringed) and, when
the session has GPS, the agent and the path it walked in this episode.</p>
<p id="status" role="status" aria-live="polite">Waiting for the first reset…</p>
<div class="pictures">
<img id="frame" alt="No picture yet: the session has not been reset.">
<img id="map" alt="No map yet: the session has not been reset.">
</div>
<h2>Metrics</h2>
<dl id="metrics"></dl>
<script>
const live = {{CONFIG}};
const status = document.getElementById("status");
const frame = document.getElementById("frame");
const map = document.getElementById("map");
const metrics = document.getElementById("metrics");
let shown = null;

function showMetrics(values) {
  metrics.replaceChildren();
  for (const [name, value] of Object.entries(values)) {
    const term = document.createElement("dt");
    term.textContent = name;
    const detail = document.createElement("dd");
    detail.textContent = typeof value === "number" ? +value.toFixed(3) : JSON.stringify(value);
    metrics.append(term, detail);
  }
}

async function poll() {
  try {
    const answer = await fetch(`${live.base}/state?env=${live.env}`, {cache: "no-store"});
    const state = await answer.json();
    if (!answer.ok) {
      status.textContent = state.error.message;
    } else if (!state.started) {
      status.textContent = "Waiting for the first reset…";
    } else {
      const key = `${state.episode_id}/${state.step}/${state.action}`;
      if (key !== shown) {
        shown = key;
        const text = `Episode ${state.episode_id} (${state.scene_id}), step ${state.step}, ` +
          `last action ${state.action ?? "reset"}`;
        const at = `env=${live.env}&at=${encodeURIComponent(key)}`;
        frame.src = `${live.base}/frame.png?part=views&${at}`;
        frame.alt = `${text}: the agent's view`;
        map.src = `${live.base}/frame.png?part=map&${at}`;
        map.alt = `${text}: the map, with the path walked in this episode`;
        status.textContent = text;
        document.body.dataset.step = state.step;
        showMetrics(state.metrics);
      }
    }
  } catch (error) {
    status.textContent = "The server does not answer (stopped?).";
  }
  setTimeout(poll, live.poll);
}
poll();
</script>
</body>
</html>
"""
