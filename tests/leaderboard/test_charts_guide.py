"""Issue 33 without a browser: the team chart's lines and ticks, the rendered guide, and the
episode pictures' room labels and outside."""

from __future__ import annotations

import datetime as dt
import re

import numpy as np

from multion.common.stats import Estimate
from multion.leaderboard.web.charts import best_over_time
from multion.leaderboard.web.guide import participant_markdown, render_guide
from multion.leaderboard.web.pages import GUIDE
from multion.leaderboard.web.queries import TeamRun

T0 = dt.datetime(2026, 11, 25, 9, 29, tzinfo=dt.timezone.utc)


def _run(k: int, method: str, score: float, seconds: float, baseline: bool = True) -> TeamRun:
    when = T0 + dt.timedelta(seconds=seconds)
    return TeamRun(
        f"r{k}", "1-on", "minival", method, "finished", baseline, when, when,
        Estimate(score, score, score),
    )  # fmt: skip


def test_the_baselines_best_so_far_is_one_line_per_method():
    runs = [_run(0, "random", 0.3, 0), _run(1, "explorer", 0.1, 30), _run(2, "random", 0.2, 60)]
    svg = best_over_time(runs, "PPL", "1-on")
    assert svg.count('class="best-line"') == 2  # random and explorer: never joined
    assert "minival · random" in svg and "minival · explorer" in svg
    team = [_run(k, r.method, r.primary.mean, 30 * k, baseline=False) for k, r in enumerate(runs)]
    assert (
        best_over_time(team, "PPL", "1-on").count('class="best-line"') == 1
    )  # a team's best overall


def test_time_ticks_are_few_enough_to_stay_apart_and_dots_stay_off_the_axes():
    runs = [_run(k, "random", 0.0 if k == 0 else 0.1 * k, 20 * k) for k in range(6)]
    svg = best_over_time(runs, "PPL", "1-on")
    ticks = re.findall(
        r'<text x="([\d.]+)" y="[\d.]+" text-anchor="(\w+)" class="tick">(\d\d:\d\d:\d\d)<', svg
    )
    assert 2 <= len(ticks) <= 4, ticks  # at a phone's text size five would run together
    xs = [float(x) for x, _, _ in ticks]
    assert all(b - a >= 8 * 0.6 * 17 for a, b in zip(xs, xs[1:], strict=False))
    assert "2026-11-25" in svg  # the date on its own line, under the first time
    axis_x = 52
    bottom = 12 + 200
    dots = re.findall(r'<circle cx="([\d.]+)" cy="([\d.]+)" r="4.5"[^>]*class="run-dot"', svg)
    assert len(dots) == len(runs)
    for cx, cy in dots:
        assert float(cx) > axis_x + 3.5 and float(cy) < bottom - 3.5


def test_the_guide_renders_only_the_participants_parts():
    html = render_guide(GUIDE.read_text(encoding="utf-8"))
    headings = re.findall(r"<h2>(.*?)</h2>", html)
    assert headings == ["For participants", "The protocol"]
    assert "<h1>" not in html  # the page has its own
    assert "<pre><code" in html and "multion submit" in html
    assert "For organisers" not in html and "## " not in html
    assert "<script" not in render_guide(
        "# x\n\n## For participants\n\n<script>alert(1)</script>\n"
    )
    assert participant_markdown("intro\n\n## Tests\n\nno\n").strip() == "intro"


def test_room_labels_keep_clear_of_markers_and_no_floor_is_drawn_white():
    from PIL import Image, ImageDraw

    from multion.scenes.registry import layout_for
    from multion.scenes.viz import OUTSIDE, label_font, picture_frame, room_labels, scene_picture

    layout = layout_for("house-00064")
    (x0, y0, _), (x1, y1, _) = layout.bounds
    grid = np.zeros((int((y1 - y0) / 0.05) + 10, int((x1 - x0) / 0.05) + 10), dtype=bool)
    origin = (x0 - 0.25, y0 - 0.25)
    frame = picture_frame(grid, origin, 0.05)
    draw = ImageDraw.Draw(Image.new("RGB", frame.image_size))
    font = label_font(frame)
    marker = room_labels(draw, layout, frame, font)[0][1]  # a goal where the first label was
    moved = room_labels(draw, layout, frame, font, keep_clear=[marker])[0][1]
    overlap_x = min(moved[2], marker[2]) - max(moved[0], marker[0])
    overlap_y = min(moved[3], marker[3]) - max(moved[1], marker[1])
    assert overlap_x <= 0 or overlap_y <= 0
    picture = np.asarray(scene_picture(layout, grid, origin, 0.05, caption=False))
    assert (picture[2, 2] == OUTSIDE).all()  # the margin: outside the house, not a grey block
