"""``--set SECTION.FIELD=VALUE`` options, shared by ``multion train`` and ``multion eval``."""

from __future__ import annotations

import json

from multion.config.ranges import ConfigError
from multion_agents.agent import ConfigOverrides


def parse_env_overrides(items: list[str]) -> ConfigOverrides:
    """``["task.max_steps=500", ...]`` → ``{"task": {"max_steps": 500}}`` (checked by the env)."""
    overrides: ConfigOverrides = {}
    for item in items:
        key, sep, raw = item.partition("=")
        section, dot, name = key.partition(".")
        if not (sep and dot and section and name):
            raise ConfigError(
                f"--set {item!r}: expected SECTION.FIELD=VALUE, e.g. task.max_steps=500"
            )
        try:
            value = json.loads(raw)
        except json.JSONDecodeError:
            value = raw
        overrides.setdefault(section, {})[name] = value
    return overrides
