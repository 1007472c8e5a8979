"""Fixtures of the report tests: small real `multion eval` runs in the empty 6 × 4 m room.

Two agents (oracle-planner, random-oracle-found) on the same four episodes for m = 1 and m = 2,
plus `random` on 2-ON with found budgets 0 and 2: every table of the report has rows.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest

from multion.config.datasets import save_dataset
from multion.sim.simulator import Simulator
from multion.task.sampling import sample_episode
from multion_agents import cli_eval
from multion_agents.report.runs import EpisodeResult, Run

ROOM = "room-6x4"
EPISODES = 4


def run_eval(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    cli_eval.add_arguments(parser)
    return cli_eval.run(parser.parse_args(argv))


@pytest.fixture(scope="session")
def report_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory holding one run directory per play, named AGENT-Mon (and
    random-2on-budget2)."""
    data = tmp_path_factory.mktemp("report-data")
    root = tmp_path_factory.mktemp("report-runs")
    grid = Simulator().load_scene(ROOM)
    rng = np.random.default_rng(7)
    datasets = {}
    for m in (1, 2):
        episodes = []
        while len(episodes) < EPISODES:
            episode = sample_episode(grid, ROOM, m, rng, f"room-{m}on-{len(episodes)}")
            if episode is not None:
                episodes.append(episode)
        datasets[m] = save_dataset(data / f"room-{m}-on.json.gz", episodes, m, "val")
    common = ["--in-process", "--pictures", "0", "--quiet", "--image-size", "16"]
    plays = [
        (f"{agent}-{m}on", ["--agent", agent, "--task", f"{m}-on", "--max-steps", "80"])
        for agent in ("oracle-planner", "random-oracle-found")
        for m in (1, 2)
    ]
    plays += [
        ("random-2on", ["--agent", "random", "--task", "2-on", "--max-steps", "80"]),
        ("random-2on-budget2", ["--agent", "random", "--task", "2-on", "--max-steps", "80"]),
    ]
    for name, argv in plays:
        m = 1 if "1on" in name else 2
        extra = ["--set", "task.found_budget=2"] if name.endswith("budget2") else []
        argv = [*argv, *common, *extra, "--dataset", str(datasets[m]), "--out", str(root / name)]
        assert run_eval(argv) == 0, name
    return root


OneGoalRun = Callable[..., Run]


@pytest.fixture
def one_goal_run() -> OneGoalRun:
    """Builds a 1-ON val run of the given episodes, without files: ``(name, episodes,
    dataset="0123456789ab")``; the agent is named as the run."""

    def build(name: str, episodes: Sequence[EpisodeResult], dataset: str = "0123456789ab") -> Run:
        return Run(path=Path(name), agent=name, num_goals=1, split="val", dataset=dataset,
                   found_budget=0, goal_set="colours", settings={}, camera_width=36,
                   renderer="tiny", seed=0, multion_version="test",
                   episodes=tuple(episodes))  # fmt: skip

    return build
