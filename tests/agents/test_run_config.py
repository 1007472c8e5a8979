"""The config a leaderboard run gives an agent (``cli_submit.run_config``) is the one the server
will play: the track's task rules, camera and oracle maps from ``GET /v1/challenge``, with the
agent's own oracle-map settings over the track's, so an agent refuses a track it cannot play
before the run starts."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Any

import pytest

from multion.config.codec import env_config_from_dict
from multion.config.task import MapConfig
from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.leaderboard.storage import Database
from multion_agents import leaderboard_baselines
from multion_agents.agent import AgentError
from multion_agents.baselines.explorer import ExplorerAgent
from multion_agents.baselines.oracle_planner import OraclePlannerAgent
from multion_agents.cli_submit import run_config
from multion_agents.registry import agent_class


def described(track: Track) -> dict[str, Any]:
    """``track`` as ``GET /v1/challenge`` describes it (the server's own code)."""
    challenge = Challenge(name="c", secret="s" * 32, tracks=(track,))
    return challenge.describe()["tracks"][0]


def test_the_tracks_rules_camera_and_maps_reach_the_agent() -> None:
    track = Track(
        "2-on-shapes", num_goals=2, kind="oracle", camera={"width": 64, "height": 48},
        maps={"ego_size": 21, "goal_cells": 1}, max_steps=300, num_distractors=1,
        success_distance=1.0, found_budget=2, goal_set="shapes", phases=(Phase("p", 2),),
    )  # fmt: skip
    config = run_config(agent_class("random"), described(track))
    task = config["task"]
    assert (task["num_goals"], task["max_steps"], task["num_distractors"]) == (2, 300, 1)
    assert (task["success_distance"], task["found_budget"], task["goal_set"]) == (1.0, 2, "shapes")
    assert (config["camera"]["width"], config["camera"]["height"]) == (64, 48)
    assert (config["maps"]["ego_size"], config["maps"]["goal_cells"]) == (21, 1)
    # the same as the env config the server builds for a run of this track
    server = env_config_from_dict(track.env_config(track.phases[0]))
    assert config["maps"] == asdict(server.maps)
    assert config["task"]["goal_set"] == server.task.goal_set


def test_an_agent_refuses_a_track_it_cannot_play_before_the_run() -> None:
    shapes = described(Track("s", num_goals=1, goal_set="shapes", phases=(Phase("p", 2),)))
    with pytest.raises(AgentError, match="goal_set='shapes'"):
        ExplorerAgent().configure(run_config(ExplorerAgent, shapes))


def test_the_agents_own_oracle_maps_win_over_the_tracks() -> None:
    track = described(
        Track("o", num_goals=1, kind="oracle", maps={"ego_size": 21}, phases=(Phase("p", 2),))
    )
    config = run_config(OraclePlannerAgent, track)
    wanted = OraclePlannerAgent.config_overrides["maps"]
    assert {k: config["maps"][k] for k in wanted} == wanted
    OraclePlannerAgent().configure(config)  # accepted: the run will ask for its own maps


def test_an_older_server_without_rules_or_maps_gives_the_defaults() -> None:
    config = run_config(agent_class("random"), {"name": "t", "num_goals": 1, "camera": {}})
    assert config["task"]["goal_set"] == "colours"
    assert config["maps"]["ego_size"] == MapConfig().ego_size


def test_the_leaderboard_baselines_skip_an_agent_the_track_refuses(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`multion leaderboard baselines` on a shapes track: the explorer (which tells goals apart
    by colour) is skipped, saying why, before any run is created (no quota spent)."""
    shapes = described(Track("s", num_goals=1, goal_set="shapes", phases=(Phase("p", 2),)))
    monkeypatch.setattr(leaderboard_baselines, "server_tracks", lambda server: [shapes])

    def no_run(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("a run was created for an agent the track refuses")

    monkeypatch.setattr(leaderboard_baselines, "RunEnv", no_run)
    db = Database.open(f"sqlite:///{tmp_path / 'board.db'}")
    try:
        runs = leaderboard_baselines.play_baselines(db, "http://unused", agents=["explorer"])
    finally:
        db.close()
    assert runs == []
    assert "s/p: explorer skipped: explorer: it tells goals apart by their colours" in (
        capsys.readouterr().out
    )
