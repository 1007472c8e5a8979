"""Episodes: a scene, a start pose and an ordered list of goals (SPEC §5)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from multion.config.ranges import ConfigError


@dataclass(frozen=True)
class Goal:
    """A goal cylinder: its category id (0..k-1) and the point of the floor it stands on."""

    category: int
    position: tuple[float, float, float]


@dataclass(frozen=True)
class Episode:
    """One MultiON episode. Positions are world metres (z up); ``start_yaw`` is radians from +x."""

    episode_id: str
    scene_id: str
    start_position: tuple[float, float, float]
    start_yaw: float
    goals: tuple[Goal, ...]
    geodesic_distances: tuple[float, ...] = field(default=(), compare=False)
    """start→g1, g1→g2, … as measured when the episode was generated (informative)."""
    distractors: tuple[Goal, ...] = ()
    """Cylinders of categories that are not among ``goals`` (the MultiON 2022 challenge's
    distractors): drawn and mapped like goals, never to be FOUND. Each stands more than twice the
    success distance from every goal, so no spot is within reach of a goal and a distractor."""

    @property
    def num_goals(self) -> int:
        return len(self.goals)

    def to_dict(self) -> dict[str, Any]:
        return {
            "episode_id": self.episode_id,
            "scene_id": self.scene_id,
            "start_position": [round(v, 4) for v in self.start_position],
            "start_yaw": round(self.start_yaw, 6),
            "goals": [
                {"category": g.category, "position": [round(v, 4) for v in g.position]}
                for g in self.goals
            ],
            "geodesic_distances": [round(d, 4) for d in self.geodesic_distances],
            "distractors": [
                {"category": d.category, "position": [round(v, 4) for v in d.position]}
                for d in self.distractors
            ],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = "episode") -> Episode:
        """Build from the JSON form, checking every field's type; raises :class:`ConfigError`
        naming the field (``episode.goals[1].category``) and what it must be. Values (scene
        ids, categories, ranges) are checked where the task is known: ``multion.task``."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"{where} must be a map, got {type(data).__name__}")
        unknown = [str(k) for k in data if k not in EPISODE_FIELDS]
        if unknown:
            raise ConfigError(
                f"unknown field '{where}.{unknown[0]:.40}'; fields of an episode are: "
                f"{', '.join(EPISODE_FIELDS)}"
            )
        missing = [k for k in REQUIRED_FIELDS if k not in data]
        if missing:
            raise ConfigError(f"missing field '{where}.{missing[0]}'")
        return cls(
            episode_id=_text(data["episode_id"], f"{where}.episode_id"),
            scene_id=_text(data["scene_id"], f"{where}.scene_id"),
            start_position=_point(data["start_position"], f"{where}.start_position"),
            start_yaw=_number(data["start_yaw"], f"{where}.start_yaw"),
            goals=_goals(data["goals"], f"{where}.goals"),
            geodesic_distances=tuple(
                _number(d, f"{where}.geodesic_distances[{i}]")
                for i, d in enumerate(
                    _list(data.get("geodesic_distances", []), f"{where}.geodesic_distances")
                )
            ),
            distractors=_goals(data.get("distractors", []), f"{where}.distractors"),
        )


REQUIRED_FIELDS = ("episode_id", "scene_id", "start_position", "start_yaw", "goals")
EPISODE_FIELDS = (*REQUIRED_FIELDS, "geodesic_distances", "distractors")
MAX_TEXT = 1024
"""Longest episode id or scene id (a mesh path included) an episode may carry: ids are echoed
in every step's infos."""


def _goals(value: Any, where: str) -> tuple[Goal, ...]:
    return tuple(_goal(g, f"{where}[{i}]") for i, g in enumerate(_list(value, where)))


def _goal(data: Any, where: str) -> Goal:
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where} must be a map with 'category' and 'position', got {data!r:.80}")
    for name in data:
        if name not in ("category", "position"):
            raise ConfigError(
                f"unknown field '{where}.{name!s:.40}'; a goal has category, position"
            )
    for name in ("category", "position"):
        if name not in data:
            raise ConfigError(f"missing field '{where}.{name}'")
    return Goal(
        category=_int(data["category"], f"{where}.category"),
        position=_point(data["position"], f"{where}.position"),
    )


def _list(value: Any, where: str) -> list[Any] | tuple[Any, ...]:
    if not isinstance(value, (list, tuple)):
        raise ConfigError(f"{where} must be a list, got {value!r:.80}")
    return value


def _point(value: Any, where: str) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise ConfigError(
            f"{where} must be a list of 3 numbers (x, y, z in metres), got {value!r:.80}"
        )
    x, y, z = (_number(v, f"{where}[{i}]") for i, v in enumerate(value))
    return (x, y, z)


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where} must be a number, got {value!r:.80}")
    try:
        return float(value)
    except OverflowError:  # an int beyond a float's range
        raise ConfigError(
            f"{where} = {value!r:.40} is out of range: allowed finite numbers"
        ) from None


def _int(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{where} must be an integer, got {value!r:.80}")
    return value


def _text(value: Any, where: str) -> str:
    if not isinstance(value, str) or not 0 < len(value) <= MAX_TEXT:
        raise ConfigError(
            f"{where} must be a non-empty string of at most {MAX_TEXT} characters, got {value!r:.80}"
        )
    return value
