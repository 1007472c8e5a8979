"""Environment configs as plain dicts (the wire form) and back, with clear errors.

A session's config is an :class:`~multion.config.task.EnvConfig` written as nested dicts, e.g.
``{"task": {"num_goals": 2}, "camera": {"width": 64, "height": 64}}``; missing fields keep their
defaults. It may also carry ``"episodes": [Episode dicts]`` to play instead of a dataset.
"""

from __future__ import annotations

import dataclasses
import functools
import types
import typing
from collections.abc import Mapping
from typing import Any

from multion.config.episode import Episode
from multion.config.ranges import ConfigError, field_ranges
from multion.config.task import EnvConfig

__all__ = [
    "ConfigError",
    "config_ranges",
    "env_config_from_dict",
    "env_config_to_dict",
    "session_config_from_dict",
]


def env_config_to_dict(config: EnvConfig) -> dict[str, Any]:
    """The nested-dict form of ``config`` (tuples become lists)."""
    plain: dict[str, Any] = _plain(dataclasses.asdict(config))
    return plain


def config_ranges(config_class: type = EnvConfig, prefix: str = "") -> dict[str, str]:
    """``{"camera.width": "an integer in [1, 1024]", ...}``: the declared range of every field."""
    ranges = {f"{prefix}{name}": spec.describe() for name, spec in field_ranges(config_class)}
    hints = _hints(config_class)
    for f in dataclasses.fields(config_class):
        if dataclasses.is_dataclass(hints[f.name]):
            ranges.update(config_ranges(hints[f.name], f"{prefix}{f.name}."))
    return ranges


def env_config_from_dict(data: Mapping[str, Any]) -> EnvConfig:
    """Build an EnvConfig from nested dicts, checking every field's name and type.

    Raises :class:`ConfigError`, e.g. ``unknown field 'camera.widht'``.
    """
    config = _build(EnvConfig, data, "")
    assert isinstance(config, EnvConfig)
    return config


def session_config_from_dict(data: Mapping[str, Any]) -> tuple[EnvConfig, list[Episode] | None]:
    """A session config: the EnvConfig plus the optional inline ``episodes``."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"config must be a map, got {type(data).__name__}")
    rest = dict(data)
    raw = rest.pop("episodes", None)
    config = env_config_from_dict(rest)
    if raw is None:
        return config, None
    if not isinstance(raw, list) or not raw:
        raise ConfigError("'episodes' must be a non-empty list of episode maps")
    episodes = []
    for index, item in enumerate(raw):
        if not isinstance(item, Mapping):
            raise ConfigError(f"episodes[{index}] must be a map, got {type(item).__name__}")
        episode = Episode.from_dict(item, f"episodes[{index}]")  # ConfigError naming the field
        if episode.num_goals != config.task.num_goals:
            raise ConfigError(
                f"episodes[{index}] ({episode.episode_id}) has {episode.num_goals} goals but "
                f"task.num_goals is {config.task.num_goals}"
            )
        episodes.append(episode)
    return config, episodes


# ---------------------------------------------------------------------- internals
@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _build(cls: type, data: Any, prefix: str) -> Any:
    where = prefix.rstrip(".") or "config"
    if not isinstance(data, Mapping):
        raise ConfigError(f"'{where}' must be a map, got {type(data).__name__}")
    hints = _hints(cls)
    known = [f.name for f in dataclasses.fields(cls) if f.init]
    values = {}
    for name, value in data.items():
        if name not in known:
            raise ConfigError(
                f"unknown field '{prefix}{name}'; fields of {where} are: {', '.join(known)}"
            )
        values[name] = _convert(hints[name], value, f"{prefix}{name}")
    try:
        return cls(**values)
    except ConfigError:
        raise  # it names the field and its range already
    except (TypeError, ValueError) as error:
        raise ConfigError(f"invalid {where}: {error}") from None


def _convert(hint: Any, value: Any, name: str) -> Any:
    """``value`` checked (and, for tuples and floats, converted) against a type hint."""
    if dataclasses.is_dataclass(hint):
        return _build(hint, value, f"{name}.")  # type: ignore[arg-type]  # is_dataclass: a class or instance
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        if len(inner) == 1 and inner[0] in (bool, int, float, str):
            if value is not None:
                try:
                    return _convert(inner[0], value, name)
                except ConfigError:
                    pass  # reported below with the full type
        elif len(inner) == 1:
            return _convert(inner[0], value, name)
    elif origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"field '{name}' must be a list, got {value!r:.80}")
        item = args[0] if len(args) == 2 and args[1] is Ellipsis else None
        if item is None:
            if len(value) != len(args):
                raise ConfigError(f"field '{name}' must have {len(args)} items, got {len(value)}")
            return tuple(
                _convert(a, v, f"{name}[{i}]")
                for i, (a, v) in enumerate(zip(args, value, strict=True))
            )
        return tuple(_convert(item, v, f"{name}[{i}]") for i, v in enumerate(value))
    elif hint is bool:
        if isinstance(value, bool):
            return value
    elif hint is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif hint is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    elif hint is str:
        if isinstance(value, str):
            return value
    else:
        raise ConfigError(f"field '{name}' has an unsupported type {hint!r}")
    raise ConfigError(
        f"field '{name}' must be {_type_name(hint)}, got {value!r:.80} ({type(value).__name__})"
    )


def _type_name(hint: Any) -> str:
    names = {bool: "a bool", int: "an int", float: "a number", str: "a string"}
    if hint in names:
        return names[hint]
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    if len(args) == 1:
        return f"{_type_name(args[0])} or null"
    return str(hint)


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value
