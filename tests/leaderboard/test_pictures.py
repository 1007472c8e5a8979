"""Run pictures (issue 21 point 7, issue 19 point 7): drawn once after a minival run ends, by a
low-priority helper process, never on a page view; room labels clear of furniture and of each
other (also ``multion scene picture``)."""

from __future__ import annotations

import asyncio
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import pytest
from PIL import Image, ImageDraw

from multion.leaderboard.challenge_file import load_challenge
from multion.leaderboard.hidden import HiddenEpisodes
from multion.leaderboard.live_run import draw_of
from multion.leaderboard.storage import Database
from multion.leaderboard.web.pictures import DISPLAY_SCALE, PictureDrawer
from multion.scenes.registry import layout_for
from multion.scenes.viz import _overlap, label_font, picture_frame, room_labels


@pytest.mark.parametrize("scene", ["house-00007", "house-00042", "house-00003", "house-00061"])
def test_room_labels_are_clear_of_each_other_and_of_furniture_where_room_allows(
    scene: str,
) -> None:
    from multion.scenes.viz import furniture_pixels
    from multion.sim.simulator import Simulator

    layout = layout_for(scene)
    sim = Simulator()
    try:
        grid = sim.load_scene(scene)
    finally:
        sim.close()
    frame = picture_frame(grid.navigable, grid.origin, grid.cell_size, 40)
    draw = ImageDraw.Draw(Image.new("RGB", frame.image_size))
    labels = room_labels(draw, layout, frame, label_font(frame))
    furniture = furniture_pixels(layout, frame)
    assert len(labels) == len(layout.rooms)
    for k, (_, box) in enumerate(labels):
        for _, other in labels[k + 1 :]:
            assert _overlap(box, other) == 0
    covered = [sum(_overlap(box, f) for f in furniture) for _, box in labels]
    # nearly every room has a free spot: at most one label in ten touches furniture
    assert sum(c > 0 for c in covered) <= len(labels) // 10, covered


def _children(pid: int) -> set[int]:
    found: set[int] = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        text = (task / "children").read_text().split()
        for child in map(int, text):
            found |= {child} | _children(child)
    return found


def test_pictures_are_drawn_after_the_run_ends_never_on_request(
    launch: Callable[..., Any],
    make_challenge: Callable[..., Path],
    new_team: Callable[[str], str],
    tmp_path: Path,
) -> None:
    from played_runs import play

    challenge_file = make_challenge(tmp_path)
    database = f"sqlite:///{tmp_path / 'results.db'}"
    Database.open(database).close()
    server = launch(challenge_file, database, {"MULTION_LEADERBOARD_DRAW_PICTURES": "false"})
    try:
        db = Database.open(database)
        with db.sessions.begin() as session:
            from multion.leaderboard.storage import add_team

            token = add_team(session, "pics")[1]
        db.close()
        run_id = play(server.url, token, "pics", "1-on", "minival", "explorer", "explorer", 0)
        page = httpx.get(f"{server.url}/leaderboard/runs/{run_id}", timeout=60).text
        assert "being drawn" in page and "<img" not in page
        before = _children(server.pid)
        # a burst of picture requests: answered from the database at once, nothing drawn
        urls = [f"{server.url}/leaderboard/runs/{run_id}/episodes/{k % 3}.png" for k in range(60)]
        started = time.monotonic()
        with ThreadPoolExecutor(12) as pool:
            codes = list(pool.map(lambda u: httpx.get(u, timeout=60).status_code, urls))
        assert codes == [404] * 60 and time.monotonic() - started < 30
        assert _children(server.pid) == before  # no drawing process was started

        # what the server's background task does after a run ended: draw and store them
        challenge = load_challenge(challenge_file)
        hidden = HiddenEpisodes(challenge, in_subprocess=False)
        db = Database.open(database)
        drawer = PictureDrawer(
            challenge, db, lambda t, p, run, r: hidden.episode(t, p, draw_of(run), r.position)
        )
        try:
            assert drawer._executor().submit(os.nice, 0).result(60) == 19  # lowest priority
            assert asyncio.run(drawer.draw_pending()) == 1
            assert asyncio.run(drawer.draw_pending()) == 0  # each run once
        finally:
            drawer.close()
            db.close()
        page = httpx.get(f"{server.url}/leaderboard/runs/{run_id}", timeout=60).text
        assert "being drawn" not in page and 'loading="lazy"' not in page
        answer = httpx.get(urls[0], timeout=60)
        assert answer.status_code == 200 and answer.headers["content-type"] == "image/png"
        width, height = int.from_bytes(answer.content[16:20]), int.from_bytes(answer.content[20:24])
        assert f'width="{width // DISPLAY_SCALE}" height="{height // DISPLAY_SCALE}"' in page
    finally:
        server.stop()
