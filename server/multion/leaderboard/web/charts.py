"""A team's best score over time, drawn on the server as an inline SVG (no script, no request).

One chart per track: a dot per run that has a score (filled: finished, hollow: ended early, its
missing episodes counted as failures; a run that played no episode to its end has none) and a step line per phase, the best score so far (per
phase and method for the organisers' baselines, which are ranked per method); each series has
its own colour, and its own marker and dash pattern (:func:`series_style`). Round ticks on
the score axis, UTC times on the time axis (the date under the time), the legend below the plot.
The chart is drawn 560 units wide and shown 360–640 px wide: text and the number of time ticks
are sized so that labels stay apart and readable on a phone (see ``PHONE_TEXT``).
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Sequence
from html import escape

from multion.leaderboard.web.queries import TeamRun

WIDTH = 560
PLOT_HEIGHT = 200
LEFT, RIGHT, TOP, AXIS = 52, 16, 12, 62
LEGEND_ROW = 24
PAD = 10
"""Units between the axes and the nearest dot: a 0 % run or the first run sits off the axes."""
PHONE_TEXT = 17
"""Font size (units) of the chart's text on a phone (style.css): about 11 px once the chart is
shrunk to a phone's width. Tick labels are spaced for it."""
CHAR_WIDTH = 0.6
"""Width of a character of the system sans-serif fonts, in ems (digits; generous)."""
SERIES_COLOURS = (
    "#0072b2", "#d55e00", "#009e73", "#cc79a7", "#e69f00", "#56b4e9", "#1d2329", "#8c564b",
)  # fmt: skip
"""Eight colours told apart also with the common colour-vision deficiencies (Okabe and Ito's
palette, its yellow swapped for brown and black softened; all readable on white)."""
MARKERS = ("circle", "square", "triangle", "diamond")
DASHES = ("", "7 4", "2 3")
"""Line patterns: with the marker, a series' shape (the first twelve are all different), for
readers who cannot tell the colours apart."""
DOT = 4.5
"""Marker radius (units): about 3 px on a phone."""
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
KEY_X = 8
"""The legend starts at the chart's left edge: its lines are the longest text."""
EPOCH = dt.datetime(2000, 1, 3, tzinfo=dt.timezone.utc)  # a Monday: weekly ticks on Mondays


def score_ticks(top: float) -> list[float]:
    """Round percent ticks from 0 covering ``top`` (a fraction): e.g. 0, 10, …, 50."""
    top_pct = max(100 * top, 5.0)  # all zeros still get an axis (0–5 %)
    step = next((s for s in SCORE_STEPS if math.ceil(top_pct / s - 1e-9) <= 5), 25)
    count = min(math.ceil(top_pct / step - 1e-9), 100 // step)
    return [k * step for k in range(count + 1)]


def time_ticks(t0: dt.datetime, t1: dt.datetime, at_most: int = 5) -> list[dt.datetime]:
    """Round UTC times in [t0, t1], at most ``at_most`` (just t0 if they are equal)."""
    span = t1 - t0
    if span <= dt.timedelta(0):
        return [t0]
    step = next((s for s in TIME_STEPS if span / s <= at_most), TIME_STEPS[-1])
    first = EPOCH + math.ceil((t0 - EPOCH) / step) * step
    ticks = []
    while first <= t1:
        ticks.append(first)
        first += step
    return ticks or [t0]


def _time_label(
    t: dt.datetime, previous: dt.datetime | None, span: dt.timedelta
) -> tuple[str, str]:
    """(first line, second line): dates for long spans, times (with seconds under 5 minutes)
    for short ones, with the date under the first tick of each day."""
    if span >= dt.timedelta(days=2):
        return (
            f"{t:%Y-%m-%d}" if previous is None or previous.year != t.year else f"{t:%m-%d}",
            "",
        )
    clock = f"{t:%H:%M:%S}" if span < dt.timedelta(minutes=5) else f"{t:%H:%M}"
    if previous is None or previous.date() != t.date():
        return clock, f"{t:%Y-%m-%d}"
    return clock, ""


def _spaced_ticks(t0: dt.datetime, t1: dt.datetime) -> list[dt.datetime]:
    """Time ticks whose labels, at the phone's text size, never run together."""
    room = WIDTH - LEFT - RIGHT - 2 * PAD
    for at_most in range(5, 1, -1):
        ticks = time_ticks(t0, t1, at_most)
        longest = max(len(max(_time_label(t, None, t1 - t0), key=len)) for t in ticks)
        if len(ticks) * (longest * CHAR_WIDTH * PHONE_TEXT + 12) <= room:
            return ticks
    return time_ticks(t0, t1, 2)


def _series(run: TeamRun) -> tuple[str, str]:
    """Which best-so-far line a run belongs to: its phase, and its method for a baseline (the
    baselines team plays several methods, each ranked on its own)."""
    return (run.phase, run.method if run.baseline else "")


def series_style(index: int) -> tuple[str, str, str]:
    """(colour, marker, dash pattern) of the ``index``-th series: eight colours, and the
    marker and dash together distinct for the first twelve series."""
    return (
        SERIES_COLOURS[index % len(SERIES_COLOURS)],
        MARKERS[index % len(MARKERS)],
        DASHES[(index // len(MARKERS)) % len(DASHES)],
    )


def marker(shape: str, x: float, y: float, fill: str, stroke: str, attributes: str = "") -> str:
    """A run's dot of ``shape`` centred on (x, y); ``attributes`` are added to the element (a
    class) and the element is left open for a ``<title>``: close it with ``</circle>`` or
    ``</path>`` as :func:`marker_end` says."""
    paint = f'fill="{fill}" stroke="{stroke}" stroke-width="1.5"{attributes}'
    if shape == "circle":
        return f'<circle cx="{x:.1f}" cy="{y:.1f}" r="{DOT}" {paint}>'
    r = DOT
    outline = {
        "square": f"M{-0.9 * r:.2f},{-0.9 * r:.2f}h{1.8 * r:.2f}v{1.8 * r:.2f}h{-1.8 * r:.2f}z",
        "triangle": f"M0,{-1.2 * r:.2f}L{1.1 * r:.2f},{0.8 * r:.2f}H{-1.1 * r:.2f}z",
        "diamond": f"M0,{-1.25 * r:.2f}L{1.25 * r:.2f},0L0,{1.25 * r:.2f}L{-1.25 * r:.2f},0z",
    }[shape]
    return f'<path transform="translate({x:.1f} {y:.1f})" d="{outline}" {paint}>'


def marker_end(shape: str) -> str:
    return "</circle>" if shape == "circle" else "</path>"


def best_over_time(runs: Sequence[TeamRun], metric_label: str, track: str) -> str:
    """The SVG of track ``track``'s runs (those with a score); empty string if none has one.
    Its name (aria-label) names the track: a page holds one chart per track."""
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
    series = list(dict.fromkeys(_series(r) for r in scored))
    height = TOP + PLOT_HEIGHT + AXIS + LEGEND_ROW * (len(series) + 2)
    bottom = TOP + PLOT_HEIGHT

    def x(t: dt.datetime) -> float:
        return LEFT + PAD + (WIDTH - LEFT - RIGHT - 2 * PAD) * (t - t0).total_seconds() / span

    def y(v: float) -> float:
        return bottom - PAD - (PLOT_HEIGHT - PAD) * (v / top if top > 0 else 0)

    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {WIDTH} {height}" role="img" '
        f'class="chart" aria-label="{escape(track)}: {escape(metric_label)} of each run over '
        'time and the best so far">',
    ]
    for tick in ticks:
        ty = y(tick / 100)
        parts.append(
            f'<line x1="{LEFT}" y1="{ty:.1f}" x2="{WIDTH - RIGHT}" y2="{ty:.1f}" class="grid"/>'
        )
        parts.append(
            f'<text x="{LEFT - 6}" y="{ty + 4:.1f}" text-anchor="end" class="tick">{tick:g}%</text>'
        )
    parts.append(
        f'<line x1="{LEFT}" y1="{bottom}" x2="{WIDTH - RIGHT}" y2="{bottom}" class="axis"/>'
    )
    parts.append(f'<line x1="{LEFT}" y1="{TOP}" x2="{LEFT}" y2="{bottom}" class="axis"/>')
    marks = [times[0]] if single else _spaced_ticks(t0, t1)
    previous = None
    for t in marks:
        tx = x(t)
        parts.append(
            f'<line x1="{tx:.1f}" y1="{bottom}" x2="{tx:.1f}" y2="{bottom + 4}" class="axis"/>'
        )
        first, second = _time_label(t, previous, t1 - t0)
        # a long label near an edge starts (or ends) at its tick rather than leaving the chart
        anchor, width = "middle", max(len(first), len(second)) * CHAR_WIDTH * PHONE_TEXT
        if tx - width / 2 < 0:
            anchor, tx = "start", max(tx - 4, 2)
        elif tx + width / 2 > WIDTH:
            anchor, tx = "end", min(tx + 4, WIDTH - 2)
        for line, text in enumerate((first, second)):
            if text:
                parts.append(
                    f'<text x="{tx:.1f}" y="{bottom + 18 + 18 * line}" text-anchor="{anchor}" '
                    f'class="tick">{text}</text>'
                )
        previous = t
    parts.append(
        f'<text x="{(LEFT + WIDTH - RIGHT) / 2:.0f}" y="{bottom + 56}" text-anchor="middle" '
        f'class="tick">when the run ended (UTC)</text>'
    )
    legend_y = bottom + AXIS + LEGEND_ROW - 4
    for index, key in enumerate(series):
        phase, method = key
        colour, shape, dash = series_style(index)
        pattern = f' stroke-dasharray="{dash}"' if dash else ""
        points: list[tuple[float, float]] = []
        best = -1.0
        for run in (r for r in scored if _series(r) == key):
            assert run.primary is not None
            px, value = x(_when(run)), run.primary.mean
            fill = colour if run.state == "finished" else "#fff"
            parts.append(
                marker(shape, px, y(value), fill, colour, f' class="run-dot" data-series="{index}"')
                + f"<title>{escape(run.method)} ({run.state}, {_when(run):%Y-%m-%d %H:%M} UTC): "
                f"{100 * value:.1f}%</title>{marker_end(shape)}"
            )
            if value > best:
                if points:
                    points.append((px, points[-1][1]))
                best = value
                points.append((px, y(best)))
        points.append((WIDTH - RIGHT - PAD, points[-1][1]))
        path = " ".join(f"{px:.1f},{py:.1f}" for px, py in points)
        parts.append(
            f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="2"{pattern} '
            f'class="best-line" data-series="{index}"/>'
        )
        ly = legend_y + LEGEND_ROW * index
        name = f"{phase} · {method}" if method else phase
        parts.append(
            f'<g class="key" data-series="{index}"><line x1="{KEY_X}" y1="{ly - 5}" '
            f'x2="{KEY_X + 26}" y2="{ly - 5}" stroke="{colour}" stroke-width="2"{pattern}/>'
            + marker(shape, KEY_X + 13, ly - 5, colour, colour)
            + marker_end(shape)
            + f'<text x="{KEY_X + 34}" y="{ly}" class="legend">{escape(name)}</text></g>'
        )
    ly = legend_y + LEGEND_ROW * len(series)
    parts.append(
        f'<text x="{KEY_X + 34}" y="{ly}" class="legend">best {escape(metric_label)} so far '
        "(line), each run (dot)</text>"
    )
    ly += LEGEND_ROW
    parts.append(
        marker("circle", KEY_X + 13, ly - 5, "#fff", "#5d6873")
        + marker_end("circle")
        + f'<text x="{KEY_X + 34}" y="{ly}" class="legend">hollow: ended early (missed episodes '
        "failed)</text>"
    )
    parts.append("</svg>")
    return "".join(parts)


def _when(run: TeamRun) -> dt.datetime:
    return run.finished_at or run.created_at
