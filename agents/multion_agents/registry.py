"""The agents ``multion eval`` knows by name, and loading agents from an import path.

Agents are found by a registry name (``random``, ``oracle-planner``, ...) or by an import path
``package.module:ClassName`` for agents that live outside this package. This module imports the
baselines; :mod:`multion_agents.agent` (the interface they implement) imports none of them.
"""

from __future__ import annotations

import importlib
import importlib.util

from multion_agents.agent import Agent, AgentError
from multion_agents.baselines.explorer import ExplorerAgent
from multion_agents.baselines.oracle_planner import OraclePlannerAgent
from multion_agents.baselines.random_agents import RandomAgent, RandomOracleFoundAgent

REGISTRY: dict[str, type[Agent]] = {
    "random": RandomAgent,
    "random-oracle-found": RandomOracleFoundAgent,
    "oracle-planner": OraclePlannerAgent,
    "explorer": ExplorerAgent,
}

AGENT_NAMES: tuple[str, ...] = tuple(REGISTRY)
"""Names accepted by :func:`agent_class` besides import paths."""

LEARNED_AGENT_NAMES: tuple[str, ...] = (
    "no-map", "oracle-map", "oracle-map-occ", "oracle-map-obj", "oracle-ego-map",
    "dynamic-oracle-map", "only-oracle-map", "oracle-map-hidden-objects",
    "dynamic-oracle-ego-map", "frmqn", "smt", "obj-recog-map", "proj-neural-map", "ego-map",
    "dynamic-obj-recog-map",
)  # fmt: skip
"""The learned agents (``multion_agents.learned.models.MODELS``, which needs torch; a test keeps
the two equal), named here so that a mistake can be explained without torch."""

SETUP_TORCH = (
    "learned agents need torch: `bash scripts/setup.sh --dev` installs it (the CPU build), or "
    "`pip install torch --index-url https://download.pytorch.org/whl/cpu` then "
    "`pip install -e '.[train]'`"
)


def torch_installed() -> bool:
    try:
        return importlib.util.find_spec("torch") is not None
    except ValueError:  # sys.modules["torch"] is None: its import is blocked
        return False


def agent_class(name: str) -> type[Agent]:
    """The class registered as ``name``, or loaded from an import path ``pkg.module:Class``."""
    if ":" not in name:
        if name in LEARNED_AGENT_NAMES:
            needs = f"; {SETUP_TORCH}" if not torch_installed() else ""
            raise AgentError(
                f"{name!r} is a learned agent: give its trained checkpoint with --checkpoint "
                f"(made by `multion train --agent {name}`){needs}"
            )
        if name not in REGISTRY:
            raise AgentError(
                f"unknown agent {name!r}; known agents: {', '.join(AGENT_NAMES)} "
                f"(or give an import path like 'my_package.my_module:MyAgent')"
            )
        return REGISTRY[name]
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
