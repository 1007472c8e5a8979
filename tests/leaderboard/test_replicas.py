"""Two server replicas sharing one PostgreSQL show the same leaderboard, and a run begun on one
continues on the other (rebuilt from the saved actions)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from multion.leaderboard.storage import Database, add_team
from multion_agents.agent import agent_class
from multion_agents.cli_submit import play_run
from multion_client.client import Client
from multion_client.run import RunEnv


def test_two_replicas_share_one_postgresql(
    postgres_url: str, challenge_file: Path, launch: Callable[..., Any]
) -> None:
    db = Database.open(postgres_url)
    with db.sessions.begin() as session:
        token = add_team(session, "replicated")[1]
    db.close()
    a = launch(challenge_file, postgres_url)
    try:
        b = launch(challenge_file, postgres_url)
        try:
            done = RunEnv(a.url, "1-on", "minival", "on-a", token=token, sensors=["goal"])
            play_run(done, agent_class("random"), progress=False)
            on_a, on_b = Client(a.url, token=token), Client(b.url, token=token)
            assert on_b.run_status(done.run_id) == on_a.run_status(done.run_id)
            assert [r.run_id for r in on_b.list_runs()] == [r.run_id for r in on_a.list_runs()]
            # a run started on A, continued on B at the same step
            going = RunEnv(a.url, "1-on", "minival", "moving", token=token, sensors=["goal", "gps"])
            going.reset()
            observation, *_ = going.step(1)
            moved = RunEnv(b.url, token=token, run_id=going.run_id)
            again, info = moved.reset()
            assert info == {"episode": 0, "seq": 1}
            np.testing.assert_array_equal(again["gps"], observation["gps"])
            moved.step(2)
            assert on_a.run_status(going.run_id).seq == 2
            moved.abandon()
        finally:
            b.stop()
    finally:
        a.stop()
