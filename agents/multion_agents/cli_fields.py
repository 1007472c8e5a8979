"""Settings dataclasses that are their own command line: one declaration per setting.

A settings field declared with :func:`setting` carries its allowed range (``multion.ranges``)
and, optionally, its command-line :class:`Option` (flag, help, a parser for special values).
:func:`add_options` builds the argparse options from the fields, :func:`from_options` builds
the settings from the parsed options, and :func:`check_settings` (called by the dataclass's
``__post_init__``) refuses a value out of range, from the command line or from code alike::

    --hidden-size must be in [1, 4096], got 0

Why not ``tyro``: our flags predate this module (``--quiet`` for ``progress=False``,
``--no-tensorboard``, ``--set`` and ``--curriculum`` parsed into nested values, ``--task 3-on``
for ``num_goals=3``) and scripts and docs use them; a small helper keeps them exactly, with
argparse's help and errors, and no new dependency.
"""

from __future__ import annotations

import argparse
import dataclasses
import typing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from multion.config.ranges import ConfigError, Range


@dataclass(frozen=True)
class Option:
    """How a settings field appears on the command line."""

    help: str
    flag: str | None = None
    """Default: ``--`` and the field name with dashes."""
    metavar: str | None = None
    parse: Callable[[Any], Any] | None = None
    """Turns the option's text (a list of texts for ``repeat``) into the field's value; raises
    ``ValueError`` with a message for the user."""
    kind: type | None = None
    """argparse's ``type`` for the text (default: the field's own type, or str with ``parse``)."""
    repeat: bool = False
    """The flag may be given several times (argparse's ``append``)."""
    negate: bool = False
    """A bool field that the flag sets to False (``--quiet`` for ``progress``)."""
    toggle: bool = False
    """A bool field with ``--flag`` and ``--no-flag``."""
    group: str | None = None
    """The title of the help section the option is listed in."""


def setting(
    default: Any = dataclasses.MISSING,
    *,
    cli: Option | None = None,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    integer: bool = False,
    choices: tuple[Any, ...] | None = None,
    default_factory: Callable[[], Any] | Any = dataclasses.MISSING,
) -> Any:
    """A settings field: its default, its allowed values (None is always allowed for a field
    whose default is None), and its command-line option."""
    metadata: dict[str, Any] = {}
    if cli is not None:
        metadata["cli"] = cli
    if low is not None or high is not None or choices is not None:
        integer = integer or (isinstance(default, int) and not isinstance(default, bool))
        metadata["range"] = Range(low, high, low_open, high_open, integer, choices)
    return dataclasses.field(default=default, default_factory=default_factory, metadata=metadata)


def flag_of(field: dataclasses.Field[Any]) -> str:
    """The flag that sets ``field`` (also how messages name it)."""
    option = field.metadata.get("cli")
    if isinstance(option, Option) and option.flag is not None:
        return option.flag
    return "--" + field.name.replace("_", "-")


def check_settings(settings: Any) -> None:
    """Raise :class:`ConfigError` (a ValueError) naming the flag of the first field of
    ``settings`` outside its range."""
    for field in dataclasses.fields(settings):
        spec = field.metadata.get("range")
        value = getattr(settings, field.name)
        if isinstance(spec, Range) and value is not None and not spec.allows(value):
            raise ConfigError(f"{flag_of(field)} must be {_allowed(spec)}, got {value!r:.80}")


def add_options(parser: argparse.ArgumentParser, settings_class: type) -> None:
    """Add an option for every field of ``settings_class`` that declares one."""
    types = typing.get_type_hints(settings_class)
    groups: dict[str, argparse._ArgumentGroup] = {}
    for field in dataclasses.fields(settings_class):
        option = field.metadata.get("cli")
        if not isinstance(option, Option):
            continue
        target: Any = parser
        if option.group is not None:
            if option.group not in groups:
                groups[option.group] = parser.add_argument_group(option.group)
            target = groups[option.group]
        target.add_argument(flag_of(field), **_argparse_keywords(field, option, types))


def from_options(settings_class: type, options: argparse.Namespace, **others: Any) -> Any:
    """The settings from parsed options (fields without an option, or whose option was not
    given and has a parser, keep their defaults; ``others`` sets further fields). Raises
    ValueError with the user's message for a bad value."""
    values: dict[str, Any] = {}
    for field in dataclasses.fields(settings_class):
        option = field.metadata.get("cli")
        if not isinstance(option, Option) or field.name not in vars(options):
            continue
        raw = getattr(options, field.name)
        values[field.name] = option.parse(raw) if option.parse is not None else raw
    return settings_class(**values, **others)


def record(settings: Any) -> dict[str, Any]:
    """The settings as JSON-ready values (for metrics.json and checkpoints)."""
    return {name: _plain(value) for name, value in dataclasses.asdict(settings).items()}


def _argparse_keywords(
    field: dataclasses.Field[Any], option: Option, types: dict[str, Any]
) -> dict[str, Any]:
    keywords: dict[str, Any] = {"dest": field.name, "help": option.help}
    if option.metavar is not None:
        keywords["metavar"] = option.metavar
    required = field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING
    if required:
        return {**keywords, "required": True}
    if option.parse is not None or option.repeat:
        # given or not given: a parsed option's default is the field's own
        keywords["default"] = argparse.SUPPRESS
        if option.kind is not None:
            keywords["type"] = option.kind
        return {**keywords, "action": "append"} if option.repeat else keywords
    keywords["default"] = field.default
    if option.toggle:
        return {**keywords, "action": argparse.BooleanOptionalAction}
    if option.negate:
        return {**keywords, "action": "store_false"}
    kind = option.kind or _plain_type(types[field.name])
    if kind is bool:
        return {**keywords, "action": "store_true"}
    return {**keywords, "type": kind}


def _plain_type(annotation: Any) -> type:
    """``int`` for ``int`` and ``int | None``; str for anything argparse cannot build."""
    candidates = [a for a in typing.get_args(annotation) if a is not type(None)] or [annotation]
    kind = candidates[0]
    return kind if kind in (int, float, str, bool) else str


def _allowed(spec: Range) -> str:
    if spec.choices is not None:
        return spec.describe()
    if spec.high is None:
        if (spec.low == 0 and spec.low_open) or (spec.integer and spec.low == 1):
            return "positive"
        if spec.low is not None and not spec.low_open:
            return f">= {spec.low:g}"
    return "in " + spec.describe().removeprefix("an integer in ")


def _plain(value: Any) -> Any:
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return value
