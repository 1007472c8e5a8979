"""Valid ranges of config fields, declared beside each field and checked at construction.

Every config dataclass (``CameraConfig``, ``AgentConfig``, ``TaskConfig`` …) declares its numeric
fields with :func:`bounded` (or :func:`one_of` for names) and calls :func:`check_fields` in
``__post_init__``. So the in-process env, the command line (``--set``) and the server (a create
request) refuse the same bad value with the same message, which names the field, the value and
the allowed range::

    camera.width = 0 is out of range: allowed [1, 1024]

The ranges bound what one environment may cost (image sizes, map crops, grid cells) and exclude
values that make no sense (an empty field of view, a negative radius, a depth range of width 0).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from multion.config.errors import UsageError
from multion_client.errors import InvalidConfig


class ConfigError(UsageError, InvalidConfig, ValueError):
    """A config value that cannot be used; the message names the field and what is allowed
    (422 ``invalid_config``; still a ``ValueError`` for the callers that caught that)."""


@dataclass(frozen=True)
class Range:
    """An interval of numbers (ends inclusive unless ``*_open``), or a set of allowed values."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    choices: tuple[Any, ...] | None = None

    def allows(self, value: Any) -> bool:
        if self.choices is not None:
            return value in self.choices
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False
        if self.integer and not isinstance(value, int):
            return False
        if not math.isfinite(value):
            return False
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        return not (
            self.high is not None and (value >= self.high if self.high_open else value > self.high)
        )

    def describe(self) -> str:
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        kind = "an integer in " if self.integer else ""
        low = "-inf" if self.low is None else _number(self.low)
        high = "inf" if self.high is None else _number(self.high)
        left = "(" if self.low_open or self.low is None else "["
        right = ")" if self.high_open or self.high is None else "]"
        return f"{kind}{left}{low}, {high}{right}"


def bounded(
    default: float,
    low: float | None = None,
    high: float | None = None,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> Any:
    """A dataclass field whose value must lie in ``[low, high]`` (integers for an int default)."""
    integer = isinstance(default, int) and not isinstance(default, bool)
    spec = Range(low, high, low_open, high_open, integer)
    return dataclasses.field(default=default, metadata={"range": spec})


def one_of(default: Any, choices: tuple[Any, ...]) -> Any:
    """A dataclass field whose value must be one of ``choices``."""
    return dataclasses.field(default=default, metadata={"range": Range(choices=choices)})


def field_ranges(config_class: type) -> Iterator[tuple[str, Range]]:
    """``(field name, Range)`` for every bounded field of a config dataclass."""
    for f in dataclasses.fields(config_class):
        spec = f.metadata.get("range")
        if isinstance(spec, Range):
            yield f.name, spec


def check_fields(config: Any, section: str) -> None:
    """Raise :class:`ConfigError` for the first field of ``config`` outside its range.

    ``section`` prefixes the field names in messages ("camera" gives ``camera.width``); "" for
    top-level fields.
    """
    for name, spec in field_ranges(type(config)):
        value = getattr(config, name)
        if not spec.allows(value):
            where = f"{section}.{name}" if section else name
            problem = "is not allowed" if spec.choices is not None else "is out of range"
            raise ConfigError(f"{where} = {value!r:.80} {problem}: allowed {spec.describe()}")


def require(condition: bool, message: str) -> None:
    """Raise :class:`ConfigError` with ``message`` unless ``condition`` (cross-field rules)."""
    if not condition:
        raise ConfigError(message)


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else repr(value)
