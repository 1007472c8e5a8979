"""Runs that play several episodes at once (lanes), over real HTTP: the server still chooses
every episode, every rule holds per lane (sequence numbers, retries, step budgets), a restart
resumes each lane at its step, the quota counts runs, and a replay re-scores exactly."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from in_process import InProcessServer

from multion.api.local_server import LocalServer
from multion.leaderboard.challenge import (
    Challenge,
    HiddenScenes,
    Limits,
    Phase,
    Track,
)
from multion.leaderboard.challenge_file import load_challenge, write_challenge
from multion.leaderboard.clock import ManualClock
from multion.leaderboard.replay import rescore
from multion.leaderboard.storage import Database, add_team
from multion_agents.cli_submit import play_lanes
from multion_agents.registry import agent_class
from multion_client import errors
from multion_client.client import Client
from multion_client.run import RunEnv
from multion_client.run_protocol import CreateRun

LANES = Challenge(
    name="lanes",
    secret="lanes-secret-0123456789abcdef",
    limits=Limits(max_consecutive_timeouts=2, max_envs_per_run=3),
    hidden=HiddenScenes(rooms=(1, 1)),
    tracks=(
        Track("1-on", num_goals=1, camera={"width": 16, "height": 16}, max_steps=12, phases=(
            Phase("test-standard", episodes=6, houses=2, feedback="aggregate"),
            Phase("once", episodes=4, houses=1, feedback="aggregate", total_quota=1),
        )),
    ),
)  # fmt: skip
STEP_TIMEOUT_S = LANES.limits.step_timeout_s


def write(directory: Path) -> Path:
    return write_challenge(LANES, directory / "lanes.toml")


@pytest.fixture(scope="module")
def lanes_challenge(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write(tmp_path_factory.mktemp("lanes"))


@pytest.fixture(scope="module")
def lanes_server(
    lanes_challenge: Path, database: str, launch: Callable[..., LocalServer]
) -> Iterator[LocalServer]:
    server = launch(lanes_challenge, database, options=("--workers", "2"))
    try:
        yield server
    finally:
        server.stop()


def test_lanes_play_a_run_and_replay_exactly(
    lanes_server: LocalServer, lanes_challenge: Path, database: str,
    new_team: Callable[[str], str],
) -> None:  # fmt: skip
    token = new_team("parallel")
    cls = agent_class("random")
    envs = RunEnv.lanes(lanes_server.url, "1-on", "test-standard", "random x3", token=token,
                        sensors=list(cls.sensors), num_envs=3)  # fmt: skip
    assert [env.lane for env in envs] == [0, 1, 2] and len({env.run_id for env in envs}) == 1
    play_lanes(envs, cls, seed=0, progress=False)
    status = envs[0].status()
    assert status.state == "finished" and status.num_envs == 3 and status.episodes_done == 6
    assert status.lanes is not None and [lane["episode"] for lane in status.lanes] == [3, 4, 5]
    db = Database.open(database)
    try:
        with db.sessions() as session:
            report = rescore(session, load_challenge(lanes_challenge), envs[0].run_id, False)
    finally:
        db.close()
    assert report["episodes"] == 6 and report["differences"] == []
    assert report["summary"]["ppl"] == status.results["ppl"]


def test_every_rule_holds_per_lane(
    lanes_server: LocalServer, new_team: Callable[[str], str]
) -> None:
    client = Client(lanes_server.url, token=new_team("rules"))
    with pytest.raises(errors.InvalidConfig, match=r"num_envs = 4 is out of range.*\[1, 3\]"):
        client.create_run(CreateRun("1-on", "test-standard", "greedy", ["goal"], num_envs=4))
    run = client.create_run(CreateRun("1-on", "test-standard", "two", ["goal"], num_envs=2))
    assert run.num_envs == 2
    with pytest.raises(errors.SequenceMismatch, match="next episode of lane 0 is 0"):
        client.start_episode(run.run_id, 2)  # no skipping ahead within a lane
    first = client.start_episode(run.run_id, 0)
    second = client.start_episode(run.run_id, 1)  # lane 1, while lane 0 plays episode 0
    assert (first.episode, second.episode) == (0, 1)
    with pytest.raises(errors.EpisodeInProgress, match="lane 0"):
        client.start_episode(run.run_id, 2)  # lane 0's next, but episode 0 is going
    with pytest.raises(errors.SequenceMismatch, match="out of range"):
        client.start_episode(run.run_id, 6)
    a = client.run_step(run.run_id, 1, 1, 2)
    b = client.run_step(run.run_id, 0, 1, 2)  # each lane counts its own steps
    assert (a.episode, a.seq, b.episode, b.seq) == (1, 1, 0, 1)
    again = client.run_step(run.run_id, 1, 1, 2)  # a retry: the stored answer, no second step
    np.testing.assert_array_equal(again.observation["goal"], a.observation["goal"])
    with pytest.raises(errors.SequenceMismatch, match="expected episode 1, seq 2"):
        client.run_step(run.run_id, 1, 3, 2)
    assert client.run_observe(run.run_id, 1).seq == 1
    with pytest.raises(errors.BadRequest, match="lanes 0..1"):
        client.run_observe(run.run_id, 2)
    client.abandon_run(run.run_id)
    status = client.run_status(run.run_id)
    # none completed (issue 53 item 3): both active ones were abandoned, 4 not played
    assert status.state == "ended" and status.episodes_done == 0


def test_the_quota_counts_runs_not_lanes(
    lanes_server: LocalServer, new_team: Callable[[str], str]
) -> None:
    client = Client(lanes_server.url, token=new_team("thrifty"))
    run = client.create_run(CreateRun("1-on", "once", "three lanes", ["goal"], num_envs=3))
    with pytest.raises(errors.QuotaExceeded):
        client.create_run(CreateRun("1-on", "once", "again", ["goal"]))
    client.abandon_run(run.run_id)


def test_a_restart_resumes_every_lane_at_its_step(
    tmp_path: Path, launch: Callable[..., LocalServer]
) -> None:
    challenge = write(tmp_path)
    database = f"sqlite:///{tmp_path / 'lanes.db'}"
    db = Database.open(database)
    with db.sessions.begin() as session:
        token = add_team(session, "restarted")[1]
    db.close()
    first = launch(challenge, database)
    try:
        client = Client(first.url, token=token)
        run = client.create_run(CreateRun("1-on", "test-standard", "r", ["rgb", "gps"], num_envs=2))
        before = {}
        for episode, actions in ((0, (1, 2, 1)), (1, (3, 1))):
            client.start_episode(run.run_id, episode)
            for seq, action in enumerate(actions, start=1):
                before[episode] = client.run_step(run.run_id, episode, seq, action)
    finally:
        first.stop()
    second = launch(challenge, database)
    try:
        client = Client(second.url, token=token)
        for lane, episode, seq in ((0, 0, 3), (1, 1, 2)):
            resumed = client.run_observe(run.run_id, lane)
            assert (resumed.episode, resumed.seq) == (episode, seq)
            for key in ("rgb", "gps"):  # the simulator state rebuilt exactly, per lane
                np.testing.assert_array_equal(
                    resumed.observation[key], before[episode].observation[key]
                )
        assert client.run_step(run.run_id, 1, 3, 1).seq == 3
        client.abandon_run(run.run_id)
    finally:
        second.stop()


def test_a_silent_lane_expires_on_its_own_budget(tmp_path: Path) -> None:
    # its own database: another server on the same one would expire this run too (as a
    # replica does), which is right, but not what this test looks at
    database = f"sqlite:///{tmp_path / 'silent.db'}"
    db = Database.open(database)
    with db.sessions.begin() as session:
        token = add_team(session, "half-silent")[1]
    db.close()
    clock = ManualClock()  # the test moves the time on: no sleeping, no race with the expiry
    with InProcessServer(write(tmp_path), database, clock) as server:
        client = Client(server.url, token=token)
        run = client.create_run(CreateRun("1-on", "test-standard", "h", ["goal"], num_envs=2))
        client.start_episode(run.run_id, 0)
        client.start_episode(run.run_id, 1)
        # lane 1 acts on time, lane 0 stays silent (both started at 0 s, budget 60 s)
        clock.advance(STEP_TIMEOUT_S - 20)
        client.run_step(run.run_id, 1, 1, 2)  # lane 1's budget: until 100 s
        clock.advance(30)  # 70 s: lane 0 is late, lane 1 is not
        status = client.run_status(run.run_id)
        assert status.state == "running" and status.lanes is not None
        assert not status.lanes[0]["episode_active"]  # scored as it stood
        assert status.lanes[1]["episode_active"]  # lane 1 was on time: it goes on
        with pytest.raises(errors.EpisodeOver, match="timeout"):
            client.run_step(run.run_id, 0, 1, 2)
        client.run_step(run.run_id, 1, 2, 2)  # lane 1's budget: until 130 s
        # 125 s: lane 0's next episode was not started in its budget (until 120 s), its second
        # expiry in a row: the run ends, although lane 1 is on time
        clock.advance(55)
        status = client.run_status(run.run_id)
        assert status.state == "ended" and status.end_reason == "timeouts"
        assert status.lanes is not None
        assert not any(lane["episode_active"] for lane in status.lanes)


def test_the_guides_lanes_example_plays_a_run(
    lanes_server: LocalServer, lanes_challenge: Path, new_team: Callable[[str], str],
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    """docs/leaderboard.md's ``RunEnv.lanes`` example, as the served guide shows it on this
    server (its host, track and phase), played to the end with an agent that always turns."""
    import re

    from multion.leaderboard.web.guide import localise, served_examples

    guide = Path(__file__).resolve().parents[2] / "docs" / "leaderboard.md"
    example = next(
        block
        for block in re.findall(r"```python\n(.*?)```", guide.read_text(encoding="utf-8"), re.S)
        if "RunEnv.lanes(" in block
    )
    served = served_examples(load_challenge(lanes_challenge), lanes_server.url)
    code = localise(example, served).replace("num_envs=4", "num_envs=3")  # this server's most
    monkeypatch.setenv("MULTION_TOKEN", new_team("guide lanes"))
    exec(compile(code, "guide-lanes-example", "exec"), {"my_agent": lambda obs: 2})  # noqa: S102
    printed = capsys.readouterr().out
    assert "'ppl'" in printed and "'mean'" in printed  # the run's results, with intervals
