"""Team pages (issue 42): every series of the chart is told apart by its colour and by its marker
and dash; a run that played no episode to its end (the leaderboard leaves it out) has no score,
no dot and no place on the best-so-far line."""

from __future__ import annotations

import re
from pathlib import Path

from stored_runs import StoredRun, pages_client, store_runs
from test_charts_guide import _run

from multion.leaderboard.challenge_file import load_challenge, write_challenge
from multion.leaderboard.storage import Database
from multion.leaderboard.web.charts import best_over_time
from multion.leaderboard.web.guide import served_examples
from multion_agents.bench.pages import bench_challenge

METHODS = ["random", "random-oracle-found", "explorer", "oracle-planner",
           "frontier", "greedy", "memory", "planner-2"]  # fmt: skip


def _styles(svg: str, element: str) -> dict[str, tuple[str, str]]:
    """series → (colour, dash) of each ``element`` (a best line, a legend line)."""
    styles = {}
    for tag in re.findall(rf"<{element} [^>]*>", svg):
        attributes = dict(re.findall(r'([\w-]+)="([^"]*)"', tag))
        if "data-series" in attributes:
            dash = attributes.get("stroke-dasharray", "")
            styles[attributes["data-series"]] = (attributes["stroke"], dash)
    return styles


def test_eight_series_have_eight_colours_and_distinct_markers_or_dashes() -> None:
    runs = [_run(k, method, 0.05 * (k + 1), 60 * k) for k, method in enumerate(METHODS)]
    svg = best_over_time(runs, "PPL", "1-on")
    lines = _styles(svg, "polyline")
    assert len(lines) == 8
    assert len({colour for colour, _ in lines.values()}) == 8, lines
    # each series' dots have one shape: circle or a path of its own outline
    shapes: dict[str, set[str]] = {}
    for element, outline, series in re.findall(
        r'<(circle|path)(?: transform="[^"]*" d="([^"]*)")?[^>]*class="run-dot" '
        r'data-series="(\d+)"',
        svg,
    ):
        shapes.setdefault(series, set()).add(outline or element)
    assert all(len(kinds) == 1 for kinds in shapes.values()), shapes
    looks = {(next(iter(shapes[s])), lines[s][1]) for s in lines}
    assert len(looks) == 8, looks  # marker and dash together: no two series alike
    # the legend shows each series as drawn: its colour, its dash and its marker
    legend = re.findall(r'<g class="key" data-series="(\d+)">(.*?)</g>', svg)
    assert len(legend) == 8
    for series, key in legend:
        colour, dash = lines[series]
        assert f'stroke="{colour}"' in key
        assert (f'stroke-dasharray="{dash}"' in key) == bool(dash)
        outline = next(iter(shapes[series]))
        assert (outline in key) if outline != "circle" else ("<circle" in key)


def test_a_run_that_played_no_episode_to_its_end_is_not_drawn(tmp_path: Path) -> None:
    challenge = write_challenge(bench_challenge(3, (("1-on", 1),)), tmp_path / "challenge.toml")
    url = f"sqlite:///{tmp_path / 'results.db'}"
    Database.open(url).close()
    scored, empty = store_runs(url, [
        StoredRun("gamma", "gamma explorer", [0.4, 0.3, 0.2], minutes=1),
        StoredRun("gamma", "gamma quitter", [None, None, None], state="ended",
                  end_reason="abandoned", missed="abandoned", minutes=5),
    ])  # fmt: skip
    with pages_client(challenge, url) as client:
        page = client.get("/leaderboard/teams/gamma").text
        board = client.get("/leaderboard").text
    assert scored in board and empty not in board  # the leaderboard leaves it out ...
    assert page.count('class="run-dot"') == 1  # ... and so does the chart
    row = re.search(rf'<tr data-run="{empty}">.*?</tr>', page, re.S)
    assert row is not None
    assert re.search(r'<td class="num key" data-value="-1">–</td>', row.group(0)), row.group(0)
    # the best-so-far line starts at the scored run: one point there, one at the right edge
    line = re.search(r'<polyline points="([^"]+)"', page)
    assert line is not None and len(line.group(1).split()) == 2


def test_the_served_guide_names_this_servers_host_and_tracks(tmp_path: Path) -> None:
    """Issue 42: its examples named a made-up host and a 3-on track this server lacks."""
    challenge = write_challenge(bench_challenge(3, (("1-on", 1),)), tmp_path / "challenge.toml")
    url = f"sqlite:///{tmp_path / 'results.db'}"
    Database.open(url).close()
    with pages_client(challenge, url) as client:
        page = client.get("/leaderboard/guide").text
    assert "--server $MULTION_SERVER --track 1-on --phase minival --agent explorer" in page
    assert "--track 1-on --phase test-standard --agent explorer" in page
    assert (
        "RunEnv(&quot;http://testserver&quot;, track=&quot;1-on&quot;, phase=&quot;minival&quot;"
        in page
    )
    assert "MULTION_TRACK=1-on" in page
    assert "--track 3-on" not in page and "challenge.example.org" not in page
    # a Host header that is not a plain host is not shown (the made-up one is)
    spoofed = served_examples(load_challenge(challenge), "http://evil.org/<b>x</b>")
    assert spoofed.url == "https://challenge.example.org" and spoofed.track == "1-on"
