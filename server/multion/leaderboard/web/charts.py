"""A team's best score over time, drawn on the server as an inline SVG (no script, no request).

One chart per track: a step line per phase, rising each time a finished run beat the team's
best so far; every run is a dot.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from html import escape

from multion.leaderboard.web.queries import TeamRun

WIDTH, HEIGHT = 560, 220
LEFT, RIGHT, TOP, BOTTOM = 48, 12, 14, 34
PHASE_COLOURS = ("#1f6fb2", "#d9731a", "#2a9d55", "#8e44ad", "#c0392b")


def best_over_time(runs: Sequence[TeamRun], metric_label: str) -> str:
    """The SVG of one track's runs (those with a score); empty string if none has one."""
    scored = sorted(
        (r for r in runs if r.primary is not None and r.finished_at is not None),
        key=lambda r: r.finished_at or r.created_at,
    )
    if not scored:
        return ""
    times = [_when(r) for r in scored]
    t0, t1 = min(times), max(times)
    span = max((t1 - t0).total_seconds(), 1.0)
    top = max(0.05, max(r.primary.mean for r in scored if r.primary is not None))
    top = min(1.0, top * 1.15)

    def x(t: dt.datetime) -> float:
        return LEFT + (WIDTH - LEFT - RIGHT) * (t - t0).total_seconds() / span

    def y(v: float) -> float:
        return TOP + (HEIGHT - TOP - BOTTOM) * (1.0 - v / top)

    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {WIDTH} {HEIGHT}" role="img" '
        f'class="chart" aria-label="best {escape(metric_label)} over time">',
        f'<line x1="{LEFT}" y1="{y(0):.1f}" x2="{WIDTH - RIGHT}" y2="{y(0):.1f}" class="axis"/>',
        f'<line x1="{LEFT}" y1="{TOP}" x2="{LEFT}" y2="{y(0):.1f}" class="axis"/>',
    ]
    for k in range(5):
        v = top * k / 4
        parts.append(
            f'<text x="{LEFT - 6}" y="{y(v) + 4:.1f}" text-anchor="end" class="tick">{100 * v:.0f}%</text>'
        )
    parts.append(f'<text x="{LEFT}" y="{HEIGHT - 8}" class="tick">{t0:%Y-%m-%d}</text>')
    if t1 != t0:
        parts.append(
            f'<text x="{WIDTH - RIGHT}" y="{HEIGHT - 8}" text-anchor="end" class="tick">{t1:%Y-%m-%d}</text>'
        )
    phases = list(dict.fromkeys(r.phase for r in scored))
    for index, phase in enumerate(phases):
        colour = PHASE_COLOURS[index % len(PHASE_COLOURS)]
        points: list[tuple[float, float]] = []
        best = -1.0
        for run in (r for r in scored if r.phase == phase):
            assert run.primary is not None
            px, value = x(_when(run)), run.primary.mean
            parts.append(
                f'<circle cx="{px:.1f}" cy="{y(value):.1f}" r="3" fill="{colour}">'
                f"<title>{escape(run.method)}: {100 * value:.1f}%</title></circle>"
            )
            if value > best:
                if points:
                    points.append((px, points[-1][1]))
                best = value
                points.append((px, y(best)))
        points.append((WIDTH - RIGHT, points[-1][1]))
        path = " ".join(f"{px:.1f},{py:.1f}" for px, py in points)
        parts.append(f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="2"/>')
        parts.append(
            f'<text x="{WIDTH - RIGHT - 4}" y="{TOP + 14 * (index + 1)}" text-anchor="end" '
            f'fill="{colour}">{escape(phase)} (best {escape(metric_label)})</text>'
        )
    parts.append("</svg>")
    return "".join(parts)


def _when(run: TeamRun) -> dt.datetime:
    return run.finished_at or run.created_at
