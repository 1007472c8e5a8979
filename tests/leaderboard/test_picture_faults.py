"""Run pictures under faults: a picture that failed to draw is tried again (and, after
``MAX_ATTEMPTS``, said to have failed rather than "being drawn" forever); replicas sharing a
database claim a run's pictures, so only one draws them and no duplicate key is written."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from sqlalchemy import delete, select

from multion.leaderboard.challenge_file import load_challenge
from multion.leaderboard.hidden import HiddenEpisodes
from multion.leaderboard.live_run import draw_of
from multion.leaderboard.models import EpisodePicture
from multion.leaderboard.storage import Database, add_team
from multion.leaderboard.web.pictures import CLAIM, MAX_ATTEMPTS, PictureDrawer


@pytest.fixture(scope="module", params=["sqlite", "postgresql"])
def played(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory,
    make_challenge: Callable[..., Path], launch: Callable[..., Any],
    new_database: Callable[..., str],
) -> Iterator[dict[str, Any]]:  # fmt: skip
    """One ended minival run (3 played episodes) and no pictures: the server draws none."""
    from played_runs import play

    directory = tmp_path_factory.mktemp("picture-faults")
    challenge_file = make_challenge(directory)
    database = new_database(request, request.param, directory)
    db = Database.open(database)
    with db.sessions.begin() as session:
        token = add_team(session, "pics")[1]
    db.close()
    server = launch(challenge_file, database, {"MULTION_LEADERBOARD_DRAW_PICTURES": "false"})
    try:
        run_id = play(server.url, token, "pics", "1-on", "minival", "random", "random", 0)
    except BaseException:
        server.stop()
        raise
    yield {"server": server, "database": database, "run_id": run_id,
           "challenge": load_challenge(challenge_file)}  # fmt: skip
    server.stop()


def pictures(database: str, run_id: str) -> dict[int, EpisodePicture]:
    db = Database.open(database)
    try:
        with db.sessions() as session:
            rows = session.scalars(select(EpisodePicture).where(EpisodePicture.run_id == run_id))
            return {row.position: row for row in rows}
    finally:
        db.close()


def forget_pictures(database: str, run_id: str) -> None:
    db = Database.open(database)
    with db.sessions.begin() as session:
        session.execute(delete(EpisodePicture).where(EpisodePicture.run_id == run_id))
    db.close()


class Drawer:
    """A PictureDrawer whose episode lookup counts its calls and fails where told."""

    def __init__(self, played: dict[str, Any], fail_at: set[int] | None = None) -> None:
        self.calls: list[int] = []
        self.fail_at = fail_at or set()
        self.hidden = HiddenEpisodes(played["challenge"], in_subprocess=False)
        self.db = Database.open(played["database"])
        self.lock = threading.Lock()
        self.drawer = PictureDrawer(played["challenge"], self.db, self.episode_of, retry_s=0.0)

    def episode_of(self, track: Any, phase: Any, run: Any, record: Any) -> Any:
        with self.lock:
            self.calls.append(record.position)
        if record.position in self.fail_at:
            raise RuntimeError("the house could not be built")
        return self.hidden.episode(track, phase, draw_of(run), record.position)

    def round(self) -> int:
        return asyncio.run(self.drawer.draw_pending())

    def close(self) -> None:
        self.drawer.close()
        self.db.close()


def test_a_failed_picture_is_tried_again_then_said_to_have_failed(played: dict[str, Any]) -> None:
    database, run_id, url = played["database"], played["run_id"], played["server"].url
    forget_pictures(database, run_id)
    flaky = Drawer(played, fail_at={0})
    try:
        assert flaky.round() == 1
        stored = pictures(database, run_id)
        assert sorted(p for p, row in stored.items() if row.png) == [1, 2]
        assert stored[CLAIM].width == 1  # one failed try, due again at once (retry_s = 0)
        page = httpx.get(f"{url}/leaderboard/runs/{run_id}", timeout=60).text
        assert page.count("<img") == 2 and "being drawn" in page
        flaky.fail_at = set()  # the fault has passed: the retry draws only what is missing
        flaky.calls.clear()
        assert flaky.round() == 1 and flaky.calls == [0]
        stored = pictures(database, run_id)
        assert sorted(stored) == [0, 1, 2] and all(row.png for row in stored.values())
        assert flaky.round() == 0  # done: never drawn again
        page = httpx.get(f"{url}/leaderboard/runs/{run_id}", timeout=60).text
        assert page.count("<img") == 3 and "being drawn" not in page
        head = httpx.head(f"{url}/leaderboard/runs/{run_id}/episodes/0.png", timeout=60)
        assert head.status_code == 200 and head.headers["content-type"] == "image/png"
    finally:
        flaky.close()
    # a picture that always fails: MAX_ATTEMPTS tries, then stored empty and said so
    forget_pictures(database, run_id)
    broken = Drawer(played, fail_at={1})
    try:
        for _ in range(MAX_ATTEMPTS):
            assert broken.round() == 1
        assert broken.round() == 0 and broken.calls.count(1) == MAX_ATTEMPTS
    finally:
        broken.close()
    stored = pictures(database, run_id)
    assert CLAIM not in stored and stored[1].png == b"" and stored[0].png and stored[2].png
    page = httpx.get(f"{url}/leaderboard/runs/{run_id}", timeout=60).text
    assert "could not be drawn" in page and "being drawn" not in page


def test_two_replicas_claim_a_run_and_only_one_draws_it(played: dict[str, Any]) -> None:
    database, run_id = played["database"], played["run_id"]
    forget_pictures(database, run_id)
    first, second = Drawer(played), Drawer(played)
    try:

        async def both() -> list[int]:
            return list(await asyncio.gather(first.drawer.draw_pending(),
                                             second.drawer.draw_pending()))  # fmt: skip

        assert sorted(asyncio.run(both())) == [0, 1]
        assert sorted([len(first.calls), len(second.calls)]) == [0, 3]
        assert first.round() == 0 and second.round() == 0
    finally:
        first.close()
        second.close()
    stored = pictures(database, run_id)
    assert sorted(stored) == [0, 1, 2] and all(row.png for row in stored.values())
