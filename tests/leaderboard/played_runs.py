"""A leaderboard filled by real runs, shared by the page tests and the browser tests."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from multion.leaderboard.models import Run
from multion.leaderboard.storage import Database
from multion_agents.cli_submit import oracle_maps, play_run
from multion_agents.registry import agent_class
from multion_client.run import RunEnv


@dataclass(frozen=True)
class PlayedRun:
    run_id: str
    team: str
    track: str
    phase: str
    method: str
    summary: dict[str, Any]


def play(
    url: str, token: str, team: str, track: str, phase: str, method: str, agent: str, seed: int
) -> str:
    cls = agent_class(agent)
    env = RunEnv(
        url, track, phase, method, token=token, sensors=list(cls.sensors), maps=oracle_maps(cls)
    )
    play_run(env, cls, seed=seed, progress=False)
    return env.run_id


def fill(url: str, database: str, new_team: Callable[[str], str]) -> dict[str, PlayedRun]:
    """Runs of two teams and the baselines on 1-on/minival, one on 1-on/test-standard and one
    on the sealed 1-on-oracle/test-challenge; returned by label with their stored summaries."""
    plan = [  # label, team, track, phase, method, agent, seed
        ("alpha-1", "alpha", "1-on", "minival", "alpha random", "random", 1),
        ("alpha-2", "alpha", "1-on", "minival", "alpha random", "random", 2),
        ("beta", "beta", "1-on", "minival", "beta explorer", "explorer", 0),
        ("baseline", "baselines", "1-on", "minival", "random", "random", 0),
        ("standard", "beta", "1-on", "test-standard", "beta explorer", "explorer", 0),
        ("sealed", "alpha", "1-on-oracle", "test-challenge", "alpha planner", "oracle-planner", 0),
    ]
    tokens: dict[str, str] = {}
    run_ids = {}
    for label, team, track, phase, method, agent, seed in plan:
        if team not in tokens:
            tokens[team] = new_team(team)
        run_ids[label] = play(url, tokens[team], team, track, phase, method, agent, seed)
    db = Database.open(database)
    try:
        with db.sessions() as session:
            played = {}
            for label, team, track, phase, method, *_ in plan:
                run = session.get(Run, run_ids[label])
                assert run is not None and run.summary is not None
                played[label] = PlayedRun(run.id, team, track, phase, method, run.summary)
            return played
    finally:
        db.close()


def percent(value: float) -> str:
    """A fraction as the pages print it."""
    return f"{100 * value:.1f}"
