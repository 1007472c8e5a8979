"""The Agent interface, the registry, and one scripted episode with metrics worked out by hand."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from multion.config.episode import Episode, Goal
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion_agents.agent import Agent, AgentError
from multion_agents.evaluate import EvalSettings, env_config, run_episode
from multion_agents.registry import AGENT_NAMES, agent_class, make_agent
from multion_client.constants import Action


class ScriptedAgent(Agent):
    """Plays a fixed list of actions, then FOUND."""

    sensors: ClassVar[tuple[str, ...]] = ("goal",)

    def __init__(self, script: list[int], seed: int = 0) -> None:
        super().__init__(seed)
        self.script = script
        self.seen: list[set[str]] = []

    def reset(self) -> None:
        self._next = 0

    def act(self, observation: dict[str, np.ndarray]) -> int:
        self.seen.append(set(observation))
        action = self.script[self._next] if self._next < len(self.script) else Action.FOUND
        self._next += 1
        return int(action)


def _room_env() -> tuple[MultiONEnv, Episode]:
    # start (1, 2) facing +x; one red goal 3.5 m ahead
    episode = Episode("hand", "room-6x4", (1.0, 2.0, 0.0), 0.0, (Goal(0, (4.5, 2.0, 0.0)),))
    config = EnvConfig(task=TaskConfig(num_goals=1), sensors=("goal", "gps"))
    return MultiONEnv(config, episodes=[episode]), episode


def test_scripted_episode_metrics_by_hand() -> None:
    env, episode = _room_env()
    # 8 forwards of 0.25 m reach x = 3.0: 1.5 m from the goal centre, 1.45 m from its
    # 5 cm footprint (≤ 1.5), so FOUND succeeds; the optimal distance is 3.5 − 0.05 ≈ 3.45 m
    agent = ScriptedAgent([Action.MOVE_FORWARD] * 8)
    record = run_episode(env, agent, episode)
    m = record.metrics
    assert m["success"] == 1.0 and m["progress"] == 1.0
    assert m["end_reason"] == "success"
    assert m["steps"] == 9 and m["collisions"] == 0
    assert m["path_length"] == pytest.approx(2.0)
    assert m["spl"] == pytest.approx(1.0)  # p = 2.0 < d ≈ 3.45, so SPL = d / max(p, d) = 1
    # the path rebuilt from GPS runs from the start to x = 3.0 along y = 2.0
    assert record.path[0] == pytest.approx([1.0, 2.0], abs=1e-4)
    assert record.path[-1] == pytest.approx([3.0, 2.0], abs=1e-4)
    # the agent saw only the sensor it asked for, not the recorded GPS
    assert all(keys == {"goal"} for keys in agent.seen)
    env.close()


def test_found_too_early_fails() -> None:
    env, episode = _room_env()
    record = run_episode(env, ScriptedAgent([Action.MOVE_FORWARD] * 4), episode)
    assert record.metrics["success"] == 0.0
    assert record.metrics["end_reason"] == "wrong_found"
    assert record.metrics["path_length"] == pytest.approx(1.0)
    env.close()


def test_registry_names() -> None:
    for name in AGENT_NAMES:
        cls = agent_class(name)
        assert issubclass(cls, Agent) and cls.sensors
        agent = make_agent(name, seed=3)
        agent.reset()


def test_unknown_agent_name_lists_known_ones() -> None:
    with pytest.raises(AgentError, match="unknown agent 'rnadom'.*random-oracle-found"):
        agent_class("rnadom")


@pytest.mark.parametrize(
    ("path", "message"),
    [
        ("no_such_module_xyz:Agent", "cannot import module"),
        ("multion_agents.agent:Missing", "has no attribute 'Missing'"),
        ("multion_agents.agent:AgentError", "not an Agent subclass"),
        ("multion_agents.agent:Agent", "is abstract"),
        (":Agent", "bad agent import path"),
    ],
)
def test_bad_import_paths(path: str, message: str) -> None:
    with pytest.raises(AgentError, match=message):
        agent_class(path)


def test_agent_from_import_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "my_team_agents.py").write_text(
        "from multion_agents.agent import Agent\n"
        "class Spinner(Agent):\n"
        "    sensors = ('goal', 'depth')\n"
        "    config_overrides = {'camera': {'width': 32, 'height': 32}}\n"
        "    def reset(self):\n"
        "        pass\n"
        "    def act(self, observation):\n"
        "        return 2\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    cls = agent_class("my_team_agents:Spinner")
    assert cls.__name__ == "Spinner"
    assert cls(seed=0).act({}) == 2
    config = env_config(EvalSettings(agent="my_team_agents:Spinner", num_goals=2), cls)
    assert config["sensors"] == ["goal", "depth", "gps"]
    assert config["camera"] == {"width": 32, "height": 32}
    assert config["task"]["num_goals"] == 2
    sys.modules.pop("my_team_agents", None)


def test_seeding_makes_random_agents_repeatable() -> None:
    first, second = make_agent("random", seed=1), make_agent("random", seed=2)
    first.seed(42)
    second.seed(42)
    observation = {"goal": np.int64(0)}
    assert [first.act(observation) for _ in range(50)] == [
        second.act(observation) for _ in range(50)
    ]


def test_baselines_take_their_environment_from_its_resolved_config() -> None:
    from multion_agents.evaluate import resolve_config

    explorer = make_agent("explorer")
    config = resolve_config({"camera": {"hfov_deg": 90.0}, "agent": {"forward_step": 0.2}})
    explorer.configure(config)
    assert explorer.camera.hfov_deg == 90.0 and explorer.camera.max_depth == 10.0  # type: ignore[attr-defined]
    assert explorer.motion.forward_step == 0.2  # type: ignore[attr-defined]
    assert explorer.env_config["camera"]["hfov_deg"] == 90.0
    with pytest.raises(AgentError, match="turn_angle_deg=25 does not divide 360"):
        explorer.configure(resolve_config({"agent": {"turn_angle_deg": 25.0}}))
    with pytest.raises(AgentError, match="tells goals apart by their colours"):
        explorer.configure(resolve_config({"task": {"goal_set": "shapes"}}))
    planner = make_agent("oracle-planner")
    with pytest.raises(AgentError, match="maps.ego_size=50"):
        planner.configure(resolve_config({}))  # the default 0.8 m crop, not the planner's map
    planner.configure(resolve_config({"maps": planner.config_overrides["maps"]}))


def test_eval_refuses_a_config_the_agent_cannot_use_before_playing() -> None:
    from multion_agents.evaluate import evaluate

    settings = EvalSettings(
        agent="explorer", in_process=True, episodes=1,
        env_overrides={"agent": {"turn_angle_deg": 25.0}},
    )  # fmt: skip
    with pytest.raises(AgentError, match="explorer: agent.turn_angle_deg=25"):
        evaluate(settings, progress=False)
    settings = EvalSettings(
        agent="oracle-planner", in_process=True, episodes=1,
        env_overrides={"maps": {"ego_size": 50}},
    )  # fmt: skip
    with pytest.raises(AgentError, match="oracle-planner reads its oracle map as"):
        evaluate(settings, progress=False)


def test_a_remote_session_config_takes_the_servers_defaults() -> None:
    from multion_agents.evaluate import session_config

    # a server whose defaults differ (another version): the agent learns what it will get
    server = {"camera": {"max_depth": 5.0, "min_depth": 0.5, "unknown_field": 1}, "future": {}}
    config = {"task": {"num_goals": 1}, "camera": {"min_depth": 0.2}, "sensors": ["goal"]}
    resolved = session_config(config, server)
    assert resolved["camera"]["max_depth"] == 5.0  # the server's default
    assert resolved["camera"]["min_depth"] == 0.2  # the request's own value
    assert resolved["maps"]["ego_size"] == 50  # not reported by that server: ours
    assert session_config(config) == session_config(config, {})
