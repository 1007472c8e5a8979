"""A run creation the server refuses leaves no run behind (issue 53 item 7): with no room in the
simulator now (``429 memory_budget_exceeded``) or a failed insert, the lanes already opened are
closed and no row exists, so the organiser's records hold only runs whose id someone was given.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from test_faults import runs_of

from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion.leaderboard import runs as runs_module
from multion.leaderboard.app import LeaderboardExtension
from multion.leaderboard.challenge import Challenge
from multion.leaderboard.challenge_file import replace_phase, write_challenge
from multion.leaderboard.settings import LeaderboardSettings
from multion.leaderboard.storage import Database, add_team, runs_counted
from multion_client import errors
from multion_client.protocol import CONTENT_TYPE, decode, encode
from multion_client.run_protocol import RUNS_PATH, CreateRun

Post = Any


@pytest.fixture
def served(challenge: Challenge, tmp_path: Path) -> Iterator[tuple[TestClient, str, str]]:
    standard = challenge.tracks[0].phase("test-standard")
    assert standard is not None
    roomy = dataclasses.replace(standard, total_quota=None, daily_quota=3)
    challenge_file = write_challenge(
        replace_phase(challenge, "1-on", roomy), tmp_path / "challenge.toml"
    )
    database = f"sqlite:///{tmp_path / 'results.db'}"
    db = Database.open(database)
    with db.sessions.begin() as session:
        token = add_team(session, "crowded")[1]
    db.close()
    leaderboard = LeaderboardSettings(
        challenge=challenge_file, database=database, warm_up=False, draw_pictures=False,
        token_cache_s=0,
    )  # fmt: skip
    app = create_app(ServerSettings(), [LeaderboardExtension(leaderboard)])
    with TestClient(app, raise_server_exceptions=False) as http:
        yield http, token, database


def _create(http: TestClient, token: str, lanes: int) -> tuple[int, dict[str, Any]]:
    headers = {"authorization": f"Bearer {token}", "content-type": CONTENT_TYPE}
    body = CreateRun("1-on", "test-standard", "m", sensors=["goal"], num_envs=lanes).to_wire()
    answer = http.post(RUNS_PATH, content=encode(body), headers=headers)
    return answer.status_code, decode(answer.content)


def test_no_room_for_a_run_refuses_it_before_it_exists(
    served: tuple[TestClient, str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    http, token, database = served
    registry = http.app.state.runs.registry  # type: ignore[attr-defined]
    real_create, calls = registry.create, []

    async def second_lane_has_no_room(*args: Any, **options: Any) -> Any:
        calls.append(1)
        if len(calls) == 2:
            raise errors.MemoryBudgetExceeded("the simulator workers have room for 0 now")
        return await real_create(*args, **options)

    monkeypatch.setattr(registry, "create", second_lane_has_no_room)
    code, refused = _create(http, token, lanes=2)
    assert code == 429 and refused["error"]["code"] == "memory_budget_exceeded", refused
    message = refused["error"]["message"]
    assert "no run was created" in message and "refunded" not in message, message
    assert runs_of(database) == []  # was: a failed, refunded run nobody learned the id of
    assert registry.live_sessions() == 0  # the first lane's session was closed again

    monkeypatch.setattr(registry, "create", real_create)
    code, info = _create(http, token, lanes=2)
    assert code == 201, info
    assert [(r.id, r.state, r.refunded) for r in runs_of(database)] == [
        (info["run_id"], "running", False)
    ]


def test_a_run_refused_at_its_insert_closes_the_lanes_it_opened(
    served: tuple[TestClient, str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    http, token, database = served
    registry = http.app.state.runs.registry  # type: ignore[attr-defined]

    def raced(*args: Any) -> None:  # another replica used the last run of the quota meanwhile
        raise errors.QuotaExceeded("1-on/test-standard: 3 runs in the last 24 hours")

    monkeypatch.setattr(runs_module, "create_run", raced)
    code, refused = _create(http, token, lanes=2)
    assert code == 429 and refused["error"]["code"] == "quota_exceeded", refused
    assert runs_of(database) == [] and registry.live_sessions() == 0


def test_a_team_over_its_quota_is_refused_before_the_simulator_is_opened(
    served: tuple[TestClient, str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    http, token, database = served
    for _ in range(3):
        assert _create(http, token, lanes=1)[0] == 201
    registry = http.app.state.runs.registry  # type: ignore[attr-defined]

    async def no_session(*args: Any, **options: Any) -> Any:
        raise AssertionError("a session was opened for a run over its quota")

    monkeypatch.setattr(registry, "create", no_session)
    code, refused = _create(http, token, lanes=1)
    assert code == 429 and refused["error"]["code"] == "quota_exceeded", refused
    db = Database.open(database)
    with db.sessions() as session:
        team = runs_of(database)[0].team_id
        assert runs_counted(session, team, "1-on", "test-standard", None) == 3
    db.close()
