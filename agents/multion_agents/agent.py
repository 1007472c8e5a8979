"""The agent interface and the registry of agents that ``multion eval`` knows by name.

An agent is a plain Python object that sees one observation dict per step and answers with an
action id (``multion_client.constants.Action``). It declares the sensors it needs and, if it
needs them, changes to the environment configuration (a finer oracle map, a smaller camera).
The evaluator builds the environment from these declarations, so the same agent runs in-process
or against a remote server without changes.

Agents are found by a registry name (``random``, ``oracle-planner``, ...) or by an import path
``package.module:ClassName`` for agents that live outside this package.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

Observation = dict[str, np.ndarray]
ConfigOverrides = dict[str, dict[str, Any]]


class AgentError(ValueError):
    """An agent that cannot be found or built; the message says what to do instead."""


class Agent(ABC):
    """A MultiON agent: ``reset`` at the start of every episode, then ``act`` once per step.

    Subclasses set ``sensors`` (the observation keys they read) and may set
    ``config_overrides``: environment config sections to change, e.g.
    ``{"maps": {"cell_size": 0.1, "ego_size": 401}}``. Randomness must come from ``self.rng``,
    which the evaluator re-seeds before every episode so results do not depend on the order in
    which episodes are run.
    """

    sensors: ClassVar[tuple[str, ...]] = ()
    config_overrides: ClassVar[ConfigOverrides] = {}

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)

    def seed(self, seed: int) -> None:
        """Restart the agent's random stream (called by the evaluator before each episode)."""
        self.rng = np.random.default_rng(seed)

    @abstractmethod
    def reset(self) -> None:
        """Forget the previous episode."""

    @abstractmethod
    def act(self, observation: Observation) -> int:
        """The next action id for this observation."""


def _registry() -> dict[str, type[Agent]]:
    # imported here so that ``import multion_agents.agent`` stays light
    from multion_agents.baselines.explorer import ExplorerAgent
    from multion_agents.baselines.oracle_planner import OraclePlannerAgent
    from multion_agents.baselines.random_agents import RandomAgent, RandomOracleFoundAgent

    return {
        "random": RandomAgent,
        "random-oracle-found": RandomOracleFoundAgent,
        "oracle-planner": OraclePlannerAgent,
        "explorer": ExplorerAgent,
    }


AGENT_NAMES: tuple[str, ...] = ("random", "random-oracle-found", "oracle-planner", "explorer")
"""Names accepted by :func:`agent_class` besides import paths."""


def agent_class(name: str) -> type[Agent]:
    """The class registered as ``name``, or loaded from an import path ``pkg.module:Class``."""
    if ":" not in name:
        registry = _registry()
        if name not in registry:
            raise AgentError(
                f"unknown agent {name!r}; known agents: {', '.join(AGENT_NAMES)} "
                f"(or give an import path like 'my_package.my_module:MyAgent')"
            )
        return registry[name]
    module_name, _, class_name = name.partition(":")
    if not module_name or not class_name:
        raise AgentError(f"bad agent import path {name!r}; expected 'package.module:ClassName'")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise AgentError(
            f"cannot import module {module_name!r} for agent {name!r}: {error}"
        ) from None
    cls = getattr(module, class_name, None)
    if cls is None:
        raise AgentError(f"module {module_name!r} has no attribute {class_name!r}")
    if not (isinstance(cls, type) and issubclass(cls, Agent)):
        raise AgentError(
            f"{name!r} is not an Agent subclass (it must derive from multion_agents.agent.Agent)"
        )
    if getattr(cls, "__abstractmethods__", None):
        missing = ", ".join(sorted(cls.__abstractmethods__))
        raise AgentError(f"agent class {name!r} is abstract: it does not implement {missing}")
    return cls


def make_agent(name: str, seed: int = 0) -> Agent:
    """Build the agent ``name`` (registry name or import path) with a seed."""
    return agent_class(name)(seed=seed)


def merge_overrides(base: dict[str, Any], overrides: ConfigOverrides) -> dict[str, Any]:
    """A copy of the config dict ``base`` with the agent's section overrides applied."""
    merged = {
        key: (dict(value) if isinstance(value, dict) else value) for key, value in base.items()
    }
    for section, values in overrides.items():
        merged[section] = {**merged.get(section, {}), **values}
    return merged
