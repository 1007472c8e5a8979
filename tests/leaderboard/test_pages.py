"""The leaderboard's web pages over HTTP, on a database filled by real runs."""

from __future__ import annotations

import html
import io
import re
from collections.abc import Callable
from typing import Any

import httpx
import pytest
from PIL import Image
from played_runs import PlayedRun, percent

from waiting import wait_until


def get(server: Any, path: str) -> httpx.Response:
    return httpx.get(server.url + path, timeout=120)


def board(page: str, track: str, phase: str) -> str:
    """The HTML of one board section."""
    match = re.search(
        rf'<section class="board" id="board-{track}-{phase}".*?</section>', page, flags=re.S
    )
    assert match, f"no board {track}/{phase}"
    return match.group(0)


def rows(section: str) -> list[str]:
    return re.findall(r"<tr data-run=.*?</tr>", section, flags=re.S)


def test_the_leaderboard_ranks_each_teams_best_run(
    server: Any, played: dict[str, PlayedRun]
) -> None:
    answer = get(server, "/leaderboard")
    assert answer.status_code == 200
    assert answer.headers["content-type"].startswith("text/html")
    assert "default-src 'none'" in answer.headers["content-security-policy"]
    assert get(server, "/").text == answer.text
    minival = board(answer.text, "1-on", "minival")
    shown = rows(minival)
    # alpha's two runs give one row (its best), beta one, the baseline one
    best_alpha = max((played["alpha-1"], played["alpha-2"]), key=lambda r: r.summary["ppl"]["mean"])
    expected = [best_alpha, played["beta"], played["baseline"]]
    assert sorted(re.search(r'data-run="(\w+)"', r).group(1) for r in shown) == sorted(
        r.run_id for r in expected
    )
    ppl = [
        float(re.search(r'data-metric="ppl">.*?"mean">([\d.]+)', r, re.S).group(1)) for r in shown
    ]
    assert ppl == sorted(ppl, reverse=True)
    for row in shown:
        run = next(r for r in expected if r.run_id in row)
        for metric in ("ppl", "progress", "success", "spl"):
            assert f'data-metric="{metric}">' in row
            cell = re.search(rf'data-metric="{metric}">(.*?)</td>', row, re.S).group(1)
            assert percent(run.summary[metric]["mean"]) in cell
        assert f"{run.summary['episodes']} / {run.summary['episodes']}" in row
        # names break only between words: each word is its own span
        assert html.escape(run.method) in re.sub(r"</?span[^>]*>", "", row)
        assert ('class="badge">baseline' in row) == (run.team == "baselines")
    first = shown[0]
    ranks = [int(re.search(r'data-value="(\d+)"', r).group(1)) for r in shown]
    assert ranks[0] == 1 and ranks == sorted(ranks)
    assert "tied" not in first  # the leader is not marked tied with itself


def test_a_sealed_phase_shows_nothing(server: Any, played: dict[str, PlayedRun]) -> None:
    page = get(server, "/leaderboard").text
    sealed = board(page, "1-on-oracle", "test-challenge")
    assert 'sealed until <span class="when">2999-01-01 00:00 UTC</span>' in sealed  # unbroken
    assert rows(sealed) == []
    assert played["sealed"].run_id not in page
    run_page = get(server, f"/leaderboard/runs/{played['sealed'].run_id}").text
    assert "sealed until" in run_page
    assert percent(played["sealed"].summary["ppl"]["mean"]) + " [" not in run_page
    team = get(server, "/leaderboard/teams/alpha").text
    sealed_row = re.search(rf'<tr data-run="{played["sealed"].run_id}">.*?</tr>', team, re.S)
    assert sealed_row and sealed_row.group(0).endswith("–</td></tr>")  # no score shown


def test_a_run_page_shows_its_results_breakdowns_and_pictures(
    server: Any, played: dict[str, PlayedRun]
) -> None:
    run = played["beta"]
    page = get(server, f"/leaderboard/runs/{run.run_id}").text
    for metric in ("ppl", "progress", "success", "spl"):
        row = re.search(rf'<tr[^>]*data-metric="{metric}">(.*?)</tr>', page, re.S).group(1)
        value = run.summary[metric]
        assert f"{percent(value['mean'])}</td>" in row
        assert f"[{percent(value['low'])}, {percent(value['high'])}]" in row
    assert "Per house" in page and "house 1" in page
    assert len(re.findall(r"<tr data-position=", page)) == run.summary["episodes"]
    pictures = drawn_pictures(server, run.run_id)
    assert 1 <= len(pictures) <= 3
    answer = get(server, pictures[0])
    assert answer.status_code == 200 and answer.headers["content-type"] == "image/png"
    with Image.open(io.BytesIO(answer.content)) as image:
        colours = image.convert("RGB").getcolors(1 << 20)
    assert any(c == (245, 130, 20) for _, c in colours)  # the agent's path, in orange
    assert get(server, f"/leaderboard/runs/{run.run_id}/episodes/99.png").status_code == 404
    # test-standard: aggregates only, no episodes, no pictures
    standard = get(server, f"/leaderboard/runs/{played['standard'].run_id}").text
    assert "Results over" in standard and "data-position=" not in standard
    assert ".png" not in standard
    picture = f"/leaderboard/runs/{played['standard'].run_id}/episodes/0.png"
    assert get(server, picture).status_code == 404


def drawn_pictures(server: Any, run_id: str, timeout_s: float = 180.0) -> list[str]:
    """The picture addresses of a run page, once the background drawer has drawn them (until
    then the page says they are being drawn and has no image)."""

    def page_once_drawn() -> str | None:
        page = get(server, f"/leaderboard/runs/{run_id}").text
        return None if "being drawn" in page else page

    page = wait_until(page_once_drawn, timeout=timeout_s, interval=0.5,
                      message="the run's pictures to be drawn")  # fmt: skip
    return re.findall(rf'src="(/leaderboard/runs/{run_id}/episodes/\d+\.png)"', page)


def test_team_and_rules_pages(server: Any, played: dict[str, PlayedRun]) -> None:
    team = get(server, "/leaderboard/teams/alpha").text
    for label in ("alpha-1", "alpha-2", "sealed"):
        assert played[label].run_id in team
    assert played["beta"].run_id not in team
    assert "<svg" in team and "best PPL over time" in team
    rules = get(server, "/leaderboard/rules").text
    for text in ("Track 1-on", "Track 1-on-oracle", "oracle_map", "<strong>60 s</strong>",
                 "<strong>24 hours</strong>", "1 in all", "<strong>1 room</strong>",
                 "up to <strong>4</strong> episodes at once", "<code>multion-pybullet</code>"):  # fmt: skip
        assert text in rules, text
    assert "1.0 hours" not in rules and "24.0" not in rules
    assert get(server, "/leaderboard/teams/nobody").status_code == 404
    assert get(server, "/leaderboard/runs/0123").status_code == 404
    assert get(server, "/leaderboard/static/sort.js").status_code == 200


@pytest.mark.parametrize(
    ("seconds", "said"),
    [(60, "60 s"), (0.5, "0.5 s"), (90, "90 s"), (120, "2 minutes"), (5400, "90 minutes"),
     (3600, "1 hour"), (86400, "24 hours"), (7 * 86400, "7 days"), (30 * 86400, "30 days")],
)  # fmt: skip
def test_time_budgets_read_as_people_say_them(seconds: float, said: str) -> None:
    from multion.leaderboard.web.pages import _duration

    assert _duration(seconds) == said


def test_pages_are_not_in_the_api_schema(server: Any) -> None:
    schema = httpx.get(server.url + "/openapi.json").json()
    assert not [p for p in schema["paths"] if not p.startswith("/v1/")]


def test_names_are_escaped_and_an_abandoned_run_counts_its_missed_episodes(
    server: Any, played: dict[str, PlayedRun], new_team: Callable[[str], str]
) -> None:
    from multion_client.run import RunEnv

    method = '<script>alert("x")</script> & co'
    env = RunEnv(server.url, "1-on", "minival", method, token=new_team("gamma"), sensors=["goal"])
    env.reset()
    env.step(0)  # FOUND: the episode ends (one played), then the run is abandoned
    env.abandon()
    # a run abandoned before any episode ended is no entry at all (no ranked "0 / 3")
    quitter = RunEnv(server.url, "1-on", "minival", "q", token=new_team("delta"), sensors=["goal"])
    quitter.abandon()
    page = get(server, "/leaderboard").text
    assert "<script>alert" not in page and "&lt;script&gt;alert(" in page
    row = next(r for r in rows(board(page, "1-on", "minival")) if env.run_id in r)
    assert "1 / 3" in row  # the two missed episodes count as failures
    assert quitter.run_id not in page and "delta" not in page
    run_page = get(server, f"/leaderboard/runs/{env.run_id}").text
    assert "<script>alert" not in run_page and "&lt;script&gt;alert(" in run_page
    assert "not_played 2" in run_page
    assert "not_played 3" in get(server, f"/leaderboard/runs/{quitter.run_id}").text


def test_pages_answer_head_and_ids_start_with_a_letter(
    server: Any, played: dict[str, PlayedRun]
) -> None:
    for path in ("/", "/leaderboard", "/leaderboard/rules", "/leaderboard/teams/alpha",
                 f"/leaderboard/runs/{played['beta'].run_id}"):  # fmt: skip
        answer = httpx.head(server.url + path, timeout=60)
        assert answer.status_code == 200, path
        assert answer.headers["content-type"].startswith("text/html") and answer.content == b""
        page = get(server, path).text
        ids = re.findall(r'\sid="([^"]*)"', page)
        assert all(re.match(r"[A-Za-z]", i) for i in ids), ids
        assert all(f'href="#{i}"' not in page or i[0].isalpha() for i in ids)
    assert "#board-1-on-minival" in get(server, f"/leaderboard/runs/{played['beta'].run_id}").text


def test_the_rules_page_links_the_guide_and_says_how_to_get_a_token(server: Any) -> None:
    rules = get(server, "/leaderboard/rules").text
    link = re.search(r'<a href="([^"]+)">the participants\' guide</a>', rules)
    assert link, "no link to the guide"
    guide = get(server, link.group(1))
    assert guide.status_code == 200 and "multion submit" in guide.text
    assert "token" in rules and "MULTION_TOKEN" in rules and "team add" in rules
    assert f"multion submit --server {server.url}" in rules


def test_metric_headings_sort_best_first(server: Any, played: dict[str, PlayedRun]) -> None:
    page = get(server, "/leaderboard").text
    minival = board(page, "1-on", "minival")
    headings = re.findall(r"<th ([^>]*)>([^<]*)</th>", minival)
    for attributes, name in headings:
        if name.endswith("%"):  # every score: best (highest) first on the first click
            assert 'data-first="descending"' in attributes, name
        if name in ("rank", "team"):
            assert "data-first" not in attributes
