"""The challenge file: reading it (:func:`load_challenge`, every value checked, every mistake
named with its field) and writing the TOML text of a :class:`Challenge` built in Python.

Tests and benches build their challenges from the config classes of :mod:`challenge` (with
``dataclasses.replace`` for a variant) and write them with :func:`write_challenge`, rather
than each keeping a TOML template of its own. Fields left at their defaults are left out, so
the file reads as an organiser would write it; :func:`load_challenge` reads it back equal.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from multion.leaderboard.challenge import (
    Challenge,
    ChallengeError,
    HiddenScenes,
    Limits,
    Phase,
    Track,
)


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


# ---------------------------------------------------------------------- reading
def load_challenge(path: str | Path, environ: Mapping[str, str] | None = None) -> Challenge:
    """Read and check a challenge file; raises :class:`ChallengeError` naming the problem."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ChallengeError(f"{path}: no such challenge file") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
        raise ChallengeError(f"{path}: not a readable TOML file ({error})") from None
    try:
        return challenge_from_dict(data, os.environ if environ is None else environ)
    except ChallengeError as error:
        raise ChallengeError(f"{path}: {error}") from None


def challenge_from_dict(data: Mapping[str, Any], environ: Mapping[str, str]) -> Challenge:
    top = _section(data, "", ("challenge", "limits", "hidden", "tracks"), ("challenge", "tracks"))
    head = _section(top["challenge"], "challenge", ("name", "secret", "secret_env"), ("name",))
    secret = _secret(head, environ)
    limits = Limits(
        **_section(
            top.get("limits", {}),
            "limits",
            ("step_timeout_s", "max_consecutive_timeouts", "run_timeout_s", "max_envs_per_run"),
        )
    )
    hidden_raw = _section(top.get("hidden", {}), "hidden", ("rooms",))
    hidden = HiddenScenes(
        **({"rooms": _pair(hidden_raw["rooms"], "hidden.rooms")} if "rooms" in hidden_raw else {})
    )
    tracks_raw = top["tracks"]
    if not isinstance(tracks_raw, list):
        raise ChallengeError("'tracks' must be an array of tables ([[tracks]])")
    return Challenge(
        name=_typed(head["name"], str, "challenge.name"),
        secret=secret,
        tracks=tuple(_track(raw, index) for index, raw in enumerate(tracks_raw)),
        limits=limits,
        hidden=hidden,
    )


def _secret(head: Mapping[str, Any], environ: Mapping[str, str]) -> str:
    if ("secret" in head) == ("secret_env" in head):
        raise ChallengeError("[challenge] needs exactly one of 'secret' or 'secret_env'")
    if "secret" in head:
        secret: str = _typed(head["secret"], str, "challenge.secret")
        return secret
    name: str = _typed(head["secret_env"], str, "challenge.secret_env")
    if not environ.get(name):
        raise ChallengeError(f"the environment variable {name} (challenge.secret_env) is not set")
    return environ[name]


def _track(raw: Any, index: int) -> Track:
    fields = (
        "name",
        "num_goals",
        "kind",
        "sensors",
        "camera",
        "maps",
        "max_steps",
        "metric",
        "num_distractors",
        "success_distance",
        "found_budget",
        "goal_set",
        "phases",
    )
    d = _section(raw, f"tracks[{index}]", fields, ("name", "num_goals", "phases"))
    where = f"tracks[{index}]"
    phases_raw = d.pop("phases")
    if not isinstance(phases_raw, list):
        raise ChallengeError(f"{where}.phases must be an array of tables ([[tracks.phases]])")
    for key in ("camera", "maps"):
        if key in d and not isinstance(d[key], Mapping):
            raise ChallengeError(f"{where}.{key} must be a table")
    if "sensors" in d:
        d["sensors"] = tuple(
            _typed(s, str, f"{where}.sensors")
            for s in _typed(d["sensors"], list, f"{where}.sensors")
        )
    _typed(d["name"], str, f"{where}.name")
    for key in ("num_goals", "max_steps", "num_distractors", "found_budget"):
        if key in d:
            _typed(d[key], int, f"{where}.{key}")
    if "success_distance" in d:
        d["success_distance"] = float(
            _typed(d["success_distance"], (int, float), f"{where}.success_distance")
        )
    if "goal_set" in d:
        _typed(d["goal_set"], str, f"{where}.goal_set")
    return Track(
        **d, phases=tuple(_phase(p, f"{where}.phases[{i}]") for i, p in enumerate(phases_raw))
    )


def _phase(raw: Any, where: str) -> Phase:
    fields = (
        "name",
        "episodes",
        "houses",
        "feedback",
        "daily_quota",
        "total_quota",
        "sealed_until",
        "max_steps",
        "episodes_per_run",
    )
    d = _section(raw, where, fields, ("name", "episodes"))
    _typed(d["name"], str, f"{where}.name")
    if "episodes_per_run" in d:
        _typed(d["episodes_per_run"], str, f"{where}.episodes_per_run")
    for key in ("episodes", "houses", "daily_quota", "total_quota", "max_steps"):
        if key in d:
            _typed(d[key], int, f"{where}.{key}")
    if "sealed_until" in d:
        d["sealed_until"] = _utc(d["sealed_until"], f"{where}.sealed_until")
    return Phase(**d)


def _utc(value: Any, where: str) -> dt.datetime:
    if isinstance(value, str):
        try:
            value = dt.datetime.fromisoformat(value.replace("Z", "+00:00"))
        except ValueError:
            raise ChallengeError(f"{where} must be a date-time like 2026-12-01T00:00:00Z") from None
    if isinstance(value, dt.date) and not isinstance(value, dt.datetime):
        value = dt.datetime(value.year, value.month, value.day)
    if not isinstance(value, dt.datetime):
        raise ChallengeError(f"{where} must be a date-time like 2026-12-01T00:00:00Z")
    return (
        value.replace(tzinfo=dt.timezone.utc)
        if value.tzinfo is None
        else value.astimezone(dt.timezone.utc)
    )


def _section(
    data: Any, where: str, known: tuple[str, ...], required: tuple[str, ...] = ()
) -> dict[str, Any]:
    label = where or "the file"
    if not isinstance(data, Mapping):
        raise ChallengeError(f"{label} must be a table, got {type(data).__name__}")
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise ChallengeError(f"{label}: unknown field(s) {unknown}; fields are {list(known)}")
    missing = [name for name in required if name not in data]
    if missing:
        raise ChallengeError(f"{label}: missing field(s) {missing}")
    return dict(data)


def _typed(value: Any, kind: type | tuple[type, ...], where: str) -> Any:
    if isinstance(value, bool) and kind is not bool or not isinstance(value, kind):
        names = " or ".join(k.__name__ for k in (kind if isinstance(kind, tuple) else (kind,)))
        raise ChallengeError(f"{where} must be {names}, got {value!r:.60}")
    return value


def _pair(value: Any, where: str) -> tuple[int, int]:
    if not isinstance(value, list) or len(value) != 2:
        raise ChallengeError(f"{where} must be [low, high], got {value!r:.60}")
    return (_typed(value[0], int, where), _typed(value[1], int, where))
