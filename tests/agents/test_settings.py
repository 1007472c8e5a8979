"""Settings declared once: the ranges on the dataclasses are checked from code and from the
command line alike, and the command-line options are generated from the fields."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from multion.config.ranges import ConfigError
from multion_agents import cli_eval
from multion_agents.baselines.explorer import ExplorerAgent, ExplorerSettings
from multion_agents.baselines.oracle_planner import OraclePlannerAgent, OraclePlannerSettings
from multion_agents.cli_fields import from_options
from multion_agents.eval_settings import EvalSettings


def _eval_options(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    cli_eval.add_arguments(parser)
    return parser.parse_args(argv)


def test_eval_options_become_settings() -> None:
    argv = ["--agent", "explorer", "--task", "2-on", "--episodes", "4", "--workers", "2"]
    argv += ["--set", "camera.hfov_deg=90", "--set", "task.found_budget=3", "--deterministic"]
    settings = from_options(EvalSettings, _eval_options(argv))
    assert settings == EvalSettings(
        agent="explorer", num_goals=2, episodes=4, workers=2, deterministic=True,
        env_overrides={"camera": {"hfov_deg": 90}, "task": {"found_budget": 3}},
    )  # fmt: skip
    defaults = from_options(EvalSettings, _eval_options(["--agent", "random"]))
    assert defaults == EvalSettings(agent="random")


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"episodes": 0}, "--episodes must be positive, got 0"),
        ({"workers": 0}, "--workers must be positive, got 0"),
        ({"max_steps": 0}, "--max-steps must be positive, got 0"),
        ({"split": "nope"}, "unknown split 'nope'"),
        ({"in_process": True, "server": "http://x"}, "exclude each other"),
    ],
)
def test_eval_settings_refuse_bad_values_from_code(change: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        EvalSettings(agent="random", **change)


def test_training_settings_refuse_bad_values_from_code() -> None:
    pytest.importorskip("torch")
    from multion_agents.learned.train_settings import Args

    with pytest.raises(ConfigError, match=r"--imitation-coef must be in \[0, 100\], got -1"):
        Args(imitation_coef=-1.0)
    with pytest.raises(ConfigError, match="--frames must be positive, got 0"):
        Args(frames=0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        Args().frames = 5  # type: ignore[misc]


def test_agent_settings_are_checked_and_passed_at_construction() -> None:
    with pytest.raises(ConfigError, match="oracle_planner.stuck_visits = 0 is out of range"):
        OraclePlannerSettings(stuck_visits=0)
    with pytest.raises(ConfigError, match="explorer.look_ahead = 9 is out of range"):
        ExplorerSettings(look_ahead=9)
    planner = OraclePlannerAgent(settings=OraclePlannerSettings(stuck_visits=7))
    assert planner.recorded_settings()["stuck_visits"] == 7
    explorer = ExplorerAgent(settings=ExplorerSettings(map_size=61))
    assert explorer.grid.size == 61 and explorer.recorded_settings()["map_size"] == 61
    assert OraclePlannerAgent().recorded_settings() == dataclasses.asdict(OraclePlannerSettings())


def test_the_expert_plans_without_lattice_searches() -> None:
    pytest.importorskip("torch")
    import sys

    from multion_agents.learned.expert import EXPERT_SETTINGS

    assert EXPERT_SETTINGS.stuck_visits == sys.maxsize
