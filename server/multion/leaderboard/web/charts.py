"""A team's best score over time, drawn on the server as an inline SVG (no script, no request).

One chart per track: a dot per run that has a score (filled: finished, hollow: ended early, its
missing episodes counted as failures) and a step line per phase, the best score so far. Round
ticks on the score axis, UTC times on the time axis, the legend below the plot.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Sequence
from html import escape

from multion.leaderboard.web.queries import TeamRun

WIDTH = 560
PLOT_HEIGHT = 200
LEFT, RIGHT, TOP, AXIS = 48, 16, 12, 40
LEGEND_ROW = 20
PHASE_COLOURS = ("#1f6fb2", "#d9731a", "#2a9d55", "#8e44ad", "#c0392b")
SCORE_STEPS = (1, 2, 5, 10, 20, 25)
"""Percent between score ticks: the smallest giving at most 5 intervals."""
TIME_STEPS = tuple(
    dt.timedelta(**unit)
    for unit in (
        {"seconds": 1}, {"seconds": 5}, {"seconds": 15}, {"seconds": 30}, {"minutes": 1}, {"minutes": 5}, {"minutes": 15}, {"minutes": 30}, {"hours": 1},
        {"hours": 3}, {"hours": 6}, {"hours": 12}, {"days": 1}, {"days": 2}, {"days": 7},
        {"days": 14}, {"days": 30}, {"days": 91}, {"days": 365},
    )
)  # fmt: skip
EPOCH = dt.datetime(2000, 1, 3, tzinfo=dt.timezone.utc)  # a Monday: weekly ticks on Mondays


def score_ticks(top: float) -> list[float]:
    """Round percent ticks from 0 covering ``top`` (a fraction): e.g. 0, 10, …, 50."""
    top_pct = max(100 * top, 5.0)  # all zeros still get an axis (0–5 %)
    step = next((s for s in SCORE_STEPS if math.ceil(top_pct / s - 1e-9) <= 5), 25)
    count = min(math.ceil(top_pct / step - 1e-9), 100 // step)
    return [k * step for k in range(count + 1)]


def time_ticks(t0: dt.datetime, t1: dt.datetime) -> list[dt.datetime]:
    """Round UTC times in [t0, t1], at most 5 (just t0 if they are equal)."""
    span = t1 - t0
    if span <= dt.timedelta(0):
        return [t0]
    step = next((s for s in TIME_STEPS if span / s <= 5), TIME_STEPS[-1])
    first = EPOCH + math.ceil((t0 - EPOCH) / step) * step
    ticks = []
    while first <= t1:
        ticks.append(first)
        first += step
    return ticks or [t0]


def _time_label(t: dt.datetime, previous: dt.datetime | None, span: dt.timedelta) -> str:
    """Dates for long spans, times (with seconds under 5 minutes) for short ones; the date
    is written on the first tick of each day."""
    if span >= dt.timedelta(days=2):
        return f"{t:%Y-%m-%d}" if previous is None or previous.year != t.year else f"{t:%m-%d}"
    clock = f"{t:%H:%M:%S}" if span < dt.timedelta(minutes=5) else f"{t:%H:%M}"
    if previous is None or previous.date() != t.date():
        return f"{t:%m-%d} {clock}"
    return clock


def best_over_time(runs: Sequence[TeamRun], metric_label: str) -> str:
    """The SVG of one track's runs (those with a score); empty string if none has one."""
    scored = sorted(
        (r for r in runs if r.primary is not None and r.finished_at is not None), key=_when
    )
    if not scored:
        return ""
    times = [_when(r) for r in scored]
    t0, t1 = min(times), max(times)
    single = t0 == t1
    if single:  # one moment: centre it in an hour
        t0, t1 = t0 - dt.timedelta(minutes=30), t1 + dt.timedelta(minutes=30)
    span = (t1 - t0).total_seconds()
    ticks = score_ticks(max(r.primary.mean for r in scored if r.primary is not None))
    top = ticks[-1] / 100
    phases = list(dict.fromkeys(r.phase for r in scored))
    height = TOP + PLOT_HEIGHT + AXIS + LEGEND_ROW * (len(phases) + 1)
    bottom = TOP + PLOT_HEIGHT

    def x(t: dt.datetime) -> float:
        return LEFT + (WIDTH - LEFT - RIGHT) * (t - t0).total_seconds() / span

    def y(v: float) -> float:
        return bottom - PLOT_HEIGHT * (v / top if top > 0 else 0)

    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {WIDTH} {height}" role="img" '
        f'class="chart" aria-label="{escape(metric_label)} of each run and the best so far">',
    ]
    for tick in ticks:
        ty = y(tick / 100)
        parts.append(f'<line x1="{LEFT}" y1="{ty:.1f}" x2="{WIDTH - RIGHT}" y2="{ty:.1f}" class="grid"/>')
        parts.append(
            f'<text x="{LEFT - 6}" y="{ty + 4:.1f}" text-anchor="end" class="tick">{tick:g}%</text>'
        )
    parts.append(f'<line x1="{LEFT}" y1="{bottom}" x2="{WIDTH - RIGHT}" y2="{bottom}" class="axis"/>')
    parts.append(f'<line x1="{LEFT}" y1="{TOP}" x2="{LEFT}" y2="{bottom}" class="axis"/>')
    marks = [times[0]] if single else time_ticks(t0, t1)
    previous = None
    for t in marks:
        tx = x(t)
        parts.append(f'<line x1="{tx:.1f}" y1="{bottom}" x2="{tx:.1f}" y2="{bottom + 4}" class="axis"/>')
        label = _time_label(t, previous, t1 - t0)
        # a long label near an edge starts (or ends) at its tick rather than leaving the chart
        anchor = "middle"
        if len(label) > 6 and tx < LEFT + 60:
            anchor, tx = "start", tx - 4
        elif len(label) > 6 and tx > WIDTH - RIGHT - 60:
            anchor, tx = "end", tx + 4
        parts.append(
            f'<text x="{tx:.1f}" y="{bottom + 16}" text-anchor="{anchor}" class="tick">{label}</text>'
        )
        previous = t
    parts.append(
        f'<text x="{(LEFT + WIDTH - RIGHT) / 2:.0f}" y="{bottom + 32}" text-anchor="middle" '
        f'class="tick">when the run ended (UTC)</text>'
    )
    legend_y = bottom + AXIS + LEGEND_ROW - 4
    for index, phase in enumerate(phases):
        colour = PHASE_COLOURS[index % len(PHASE_COLOURS)]
        points: list[tuple[float, float]] = []
        best = -1.0
        for run in (r for r in scored if r.phase == phase):
            assert run.primary is not None
            px, value = x(_when(run)), run.primary.mean
            fill = colour if run.state == "finished" else "#fff"
            parts.append(
                f'<circle cx="{px:.1f}" cy="{y(value):.1f}" r="3.5" fill="{fill}" stroke="{colour}" '
                f'stroke-width="1.5" class="run-dot"><title>{escape(run.method)} ({run.state}, '
                f"{_when(run):%Y-%m-%d %H:%M} UTC): {100 * value:.1f}%</title></circle>"
            )
            if value > best:
                if points:
                    points.append((px, points[-1][1]))
                best = value
                points.append((px, y(best)))
        points.append((WIDTH - RIGHT, points[-1][1]))
        path = " ".join(f"{px:.1f},{py:.1f}" for px, py in points)
        parts.append(
            f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="2" '
            'class="best-line"/>'
        )
        ly = legend_y + LEGEND_ROW * index
        parts.append(
            f'<line x1="{LEFT}" y1="{ly - 4}" x2="{LEFT + 22}" y2="{ly - 4}" stroke="{colour}" stroke-width="2"/>'
            f'<circle cx="{LEFT + 11}" cy="{ly - 4}" r="3.5" fill="{colour}"/>'
            f'<text x="{LEFT + 30}" y="{ly}" class="legend">{escape(phase)}: best {escape(metric_label)} '
            "so far (line), each run (dot)</text>"
        )
    ly = legend_y + LEGEND_ROW * len(phases)
    parts.append(
        f'<circle cx="{LEFT + 11}" cy="{ly - 4}" r="3.5" fill="#fff" stroke="#5d6873" stroke-width="1.5"/>'
        f'<text x="{LEFT + 30}" y="{ly}" class="legend">hollow: ended early (missed episodes '
        "failed)</text>"
    )
    parts.append("</svg>")
    return "".join(parts)


def _when(run: TeamRun) -> dt.datetime:
    return run.finished_at or run.created_at
