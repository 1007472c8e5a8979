"""The agent interface: what every MultiON agent implements.

An agent is a plain Python object that sees one observation dict per step and answers with an
action id (``multion_client.constants.Action``). It declares the sensors it needs and, if it
needs them, changes to the environment configuration (a finer oracle map, a smaller camera).
The evaluator builds the environment from these declarations, so the same agent runs in-process
or against a remote server without changes.

The names ``multion eval`` knows agents by live in :mod:`multion_agents.registry`; this module
only defines the interface, so agents (the baselines, your own) can import it without cycles.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from multion.config.errors import UsageError

Observation = dict[str, np.ndarray]
ConfigOverrides = dict[str, dict[str, Any]]
EnvConfigDict = dict[str, Any]
"""A resolved environment config as nested dicts (every field, defaults included)."""


class AgentError(UsageError, ValueError):
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
        self.env_config: EnvConfigDict = {}
        """The environment's resolved config (:meth:`configure`); empty until then."""

    def seed(self, seed: int) -> None:
        """Restart the agent's random stream (called by the evaluator before each episode)."""
        self.rng = np.random.default_rng(seed)

    def recorded_settings(self) -> dict[str, Any]:
        """The agent's own tunables, recorded in ``metrics.json`` by ``multion eval`` (an agent
        with settings returns them, e.g. ``dataclasses.asdict(self.settings)``); none here."""
        return {}

    def configure(self, config: EnvConfigDict) -> None:
        """Receive the resolved config of the environment the agent acts in, before its first
        episode: every field with defaults filled in, as nested dicts (``camera``, ``agent``,
        ``maps``, ``task``, ...; ``multion.config.codec.env_config_to_dict``). ``multion eval``
        passes the session's config, ``multion submit`` the run's.

        An agent whose decisions depend on the environment (camera model, step length, turn
        angle, map geometry) reads them here instead of copying defaults, and raises
        :class:`AgentError` naming the field for a config it cannot use. The default keeps the
        config in ``self.env_config``."""
        self.env_config = config

    @abstractmethod
    def reset(self) -> None:
        """Forget the previous episode."""

    @abstractmethod
    def act(self, observation: Observation) -> int:
        """The next action id for this observation."""


def merge_overrides(base: dict[str, Any], overrides: ConfigOverrides) -> dict[str, Any]:
    """A copy of the config dict ``base`` with the agent's section overrides applied."""
    merged = {
        key: (dict(value) if isinstance(value, dict) else value) for key, value in base.items()
    }
    for section, values in overrides.items():
        merged[section] = {**merged.get(section, {}), **values}
    return merged
