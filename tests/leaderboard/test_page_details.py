"""Issue 53 item 4, the pages' details without a browser: ``/favicon.ico`` is served (it was a
404 on every page), each team chart's name says which track it shows (two charts of a page had
one name), and ``/leaderboard/guide`` shows the introduction's two tables as the docs say."""

from __future__ import annotations

import io
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from PIL import Image
from stored_runs import StoredRun, pages_client, store_runs

from multion.leaderboard.challenge_file import write_challenge
from multion.leaderboard.storage import Database
from multion.leaderboard.web.guide import render_guide
from multion.leaderboard.web.pages import GUIDE
from multion_agents.bench.pages import bench_challenge


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """The pages of a two-track challenge where one team has runs on both tracks."""
    directory = tmp_path_factory.mktemp("details")
    challenge = write_challenge(
        bench_challenge(4, (("1-on", 1), ("3-on", 3))), directory / "challenge.toml"
    )
    url = f"sqlite:///{directory / 'results.db'}"
    Database.open(url).close()
    store_runs(url, [
        StoredRun("two tracks", "m", [0.2, 0.4, 0.1, 0.3], track="1-on", minutes=1),
        StoredRun("two tracks", "m", [0.5, 0.4, 0.1, 0.3], track="1-on", minutes=5),
        StoredRun("two tracks", "m", [0.1, 0.0, 0.1, 0.2], track="3-on", minutes=3),
    ])  # fmt: skip
    with pages_client(challenge, url) as client:
        yield client


def test_the_favicon_is_an_icon(client: Any) -> None:
    answer = client.get("/favicon.ico")
    assert (
        answer.status_code == 200 and answer.headers["content-type"] == "image/vnd.microsoft.icon"
    )
    assert "max-age" in answer.headers["cache-control"]
    icon = Image.open(io.BytesIO(answer.content))
    assert icon.format == "ICO" and {(16, 16), (32, 32), (48, 48)} <= set(icon.info["sizes"])
    assert client.head("/favicon.ico").status_code in (200, 405)  # GET is what browsers ask


def test_each_team_chart_names_its_track(client: Any) -> None:
    page = client.get("/leaderboard/teams/two tracks").text
    labels = re.findall(r'<svg [^>]*role="img"[^>]*aria-label="([^"]*)"', page)
    assert len(labels) == 2 and len(set(labels)) == 2, labels
    assert labels[0].startswith("1-on: ") and labels[1].startswith("3-on: "), labels


def test_the_guide_shows_the_introductions_two_tables(client: Any) -> None:
    text = GUIDE.read_text(encoding="utf-8")
    intro = text[: text.index("\n## ")]
    assert intro.count("\n| --- | --- |") == 2  # the docs' introduction: two tables
    for html in (render_guide(text), client.get("/leaderboard/guide").text):
        headers = re.findall(r"<thead>\s*<tr>\s*<th>([^<]*)</th>", html)
        assert headers[:2] == ["who", "known problem"], headers
        assert "quota burnt by crashes and dropped connections" in html
    page = client.get("/leaderboard/guide").text
    assert page.count('aria-label="Table 1 ') == 1 and 'aria-label="Table 2 ' in page


def test_the_first_page_views_after_a_start_compile_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The first run page after a start took 0.6-1.5 s against 10-16 ms warm: Jinja compiled
    its templates and SQLAlchemy its statements at that first view. The server now does both
    as it starts (``warm_up``), so the first views compile no template and no statement."""
    from fastapi.testclient import TestClient

    from multion.api.app import create_app
    from multion.api.settings import ServerSettings
    from multion.leaderboard.app import LeaderboardExtension
    from multion.leaderboard.settings import LeaderboardSettings
    from multion.leaderboard.web.pages import templates

    challenge = write_challenge(bench_challenge(2, (("1-on", 1),)), tmp_path / "challenge.toml")
    url = f"sqlite:///{tmp_path / 'results.db'}"
    Database.open(url).close()
    (run_id,) = store_runs(url, [StoredRun("warm", "m", [0.2, 0.4], phase="test-standard")])
    monkeypatch.setattr(templates.env, "cache", type(templates.env.cache)(50))  # cold
    compiled: list[str] = []
    compile_template = templates.env.compile

    def counted(source: str, name: str | None = None, *args: Any, **options: Any) -> Any:
        compiled.append(str(name))
        return compile_template(source, name, *args, **options)

    monkeypatch.setattr(templates.env, "compile", counted)
    settings = LeaderboardSettings(challenge=challenge, database=url, draw_pictures=False,
                                   videos=False)  # fmt: skip
    app = create_app(ServerSettings(workers=1), [LeaderboardExtension(settings)])
    with TestClient(app) as client:
        assert {"run.html", "team.html", "leaderboard.html", "base.html"} <= set(compiled)
        statements = app.state.runs.db.engine._compiled_cache  # SQLAlchemy's, per engine
        compiled.clear()
        before = len(statements)
        for path in (f"/leaderboard/runs/{run_id}", "/leaderboard/teams/warm", "/leaderboard"):
            assert client.get(path).status_code == 200, path
        assert compiled == [] and len(statements) == before
