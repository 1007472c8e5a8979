"""Issue 42 part 6, what a participant meets first: a float action is refused on every path
(the light client's ``RunEnv`` and the server alike, as the in-process env refuses it), and
``multion submit --resume`` counts the episode it resumes once."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from multion_agents.cli import main
from multion_client import errors
from multion_client.client import Client
from multion_client.constants import Action
from multion_client.run import RunEnv


def new_run(server: Any, token: str) -> RunEnv:
    return RunEnv(server.url, "1-on", "minival", "defects", token=token, sensors=["goal", "gps"])


def test_a_float_action_is_refused_by_the_client_and_the_server(
    server: Any, new_team: Callable[[str], str]
) -> None:
    token = new_team("float actions")
    env = new_run(server, token)
    try:
        env.reset()
        with pytest.raises(errors.InvalidAction, match=r"1\.0.*integer in \[0, 3\]"):
            env.step(1.0)  # type: ignore[arg-type]
        # the same float sent by hand: the server refuses it too (it took 1.0 as 1)
        with Client(server.url, token=token) as client, pytest.raises(errors.InvalidAction) as hit:
            client.run_step(env.run_id, 0, 1, 1.0)
        assert hit.value.status == 400 and "'action'" in str(hit.value)
        assert env.status().seq == 0  # neither took a step
        _, _, _, _, info = env.step(Action.MOVE_FORWARD)  # an int still plays
        assert info["seq"] == 1
    finally:
        env.abandon()
        env.close()


def test_resume_counts_the_episode_in_progress_once(
    server: Any,
    new_team: Callable[[str], str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    token = new_team("resume count")
    monkeypatch.setenv("MULTION_TOKEN", token)
    env = new_run(server, token)
    env.reset()
    env.step(Action.FOUND)  # episode 0 ends
    env.reset()
    env.step(Action.TURN_LEFT)  # episode 1 in progress: the client "crashes" here
    env.close()
    code = main(["submit", "--server", server.url, "--resume", env.run_id, "--agent", "random"])
    out, err = capsys.readouterr()
    assert code == 0 and "finished" in out, err
    bar = err.replace("\r", "\n")
    assert "3/3" in bar and "4/3" not in bar  # 1 done before, then episodes 1 and 2
    assert "| 1/3" in bar  # the bar starts at the one episode already finished


def test_resume_of_a_finished_run_plays_nothing_and_counts_its_episodes(
    server: Any,
    new_team: Callable[[str], str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Issue 53 item 3: ``--resume`` of a finished run showed a progress bar at 0/3."""
    token = new_team("resume finished")
    monkeypatch.setenv("MULTION_TOKEN", token)
    env = new_run(server, token)
    while not env.run_done:
        env.reset()
        env.step(Action.FOUND)  # each episode ends at once
    env.close()
    code = main(["submit", "--server", server.url, "--resume", env.run_id, "--agent", "random"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert f"run {env.run_id} is over already: nothing left to play" in out
    assert "finished, 3/3 episodes completed" in out
    assert "0/3" not in err.replace("\r", "\n")  # no progress bar of a run with nothing to play
