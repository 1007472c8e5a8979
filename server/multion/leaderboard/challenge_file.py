"""Writing a challenge file: the TOML text of a :class:`Challenge` built in Python.

Tests and benches build their challenges from the config classes of :mod:`challenge` (with
``dataclasses.replace`` for a variant) and write them with :func:`write_challenge`, rather
than each keeping a TOML template of its own. Fields left at their defaults are left out, so
the file reads as an organiser would write it; :func:`load_challenge` reads it back equal.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from multion.leaderboard.challenge import Challenge, Phase, Track


def challenge_toml(challenge: Challenge) -> str:
    """The challenge file's text (the secret written out, never ``secret_env``)."""
    sections = [_table("challenge", {"name": challenge.name, "secret": challenge.secret})]
    limits = _changed(challenge.limits)
    if limits:
        sections.append(_table("limits", limits))
    if challenge.hidden.rooms is not None:
        sections.append(_table("hidden", {"rooms": challenge.hidden.rooms}))
    for track in challenge.tracks:
        sections.append(_table("[tracks]", _changed(track, leave_out=("phases",))))
        sections += [_table("[tracks.phases]", _changed(phase)) for phase in track.phases]
    return "\n".join(sections)


def write_challenge(challenge: Challenge, path: Path) -> Path:
    """Write ``challenge`` to ``path`` (a ``.toml`` file); returns ``path``."""
    path.write_text(challenge_toml(challenge), encoding="utf-8")
    return path


def replace_phase(challenge: Challenge, track_name: str, phase: Phase) -> Challenge:
    """``challenge`` with ``phase`` in place of the phase of the same name on ``track_name``."""

    def swapped(track: Track) -> Track:
        if track.name != track_name:
            return track
        phases = tuple(phase if p.name == phase.name else p for p in track.phases)
        return dataclasses.replace(track, phases=phases)

    return dataclasses.replace(challenge, tracks=tuple(swapped(t) for t in challenge.tracks))


def _changed(config: Any, leave_out: tuple[str, ...] = ()) -> dict[str, Any]:
    """A config dataclass's fields that are required or differ from their defaults."""
    changed = {}
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if f.name in leave_out:
            continue
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:  # required
            changed[f.name] = value
            continue
        if value != default:
            changed[f.name] = value
    return changed


def _table(header: str, values: Mapping[str, Any]) -> str:
    lines = [f"[{header}]", *(f"{key} = {_value(value)}" for key, value in values.items())]
    return "\n".join(lines) + "\n"


def _value(value: Any) -> str:
    """A TOML value: the types a challenge file holds."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string: JSON's escapes are TOML's
    if isinstance(value, dt.datetime):
        return value.astimezone(dt.timezone.utc).isoformat().replace("+00:00", "Z")
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{k} = {_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {value!r:.60}")
