"""Episodes: a scene, a start pose and an ordered list of goals (SPEC §5)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any


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
    def from_dict(cls, data: Mapping[str, Any]) -> Episode:
        """Build from the JSON form; raises ``ValueError``/``KeyError``/``TypeError`` on bad data."""
        return cls(
            episode_id=str(data["episode_id"]),
            scene_id=str(data["scene_id"]),
            start_position=_point(data["start_position"], "start_position"),
            start_yaw=float(data["start_yaw"]),
            goals=tuple(_goal(g, "goal") for g in data["goals"]),
            geodesic_distances=tuple(float(d) for d in data.get("geodesic_distances", ())),
            distractors=tuple(_goal(d, "distractor") for d in data.get("distractors", ())),
        )


def _goal(data: Any, name: str) -> Goal:
    return Goal(
        category=_int(data["category"], f"{name} category"),
        position=_point(data["position"], f"{name} position"),
    )


def _point(value: Any, name: str) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise ValueError(f"{name} must be a list of 3 numbers, got {value!r}")
    return (float(value[0]), float(value[1]), float(value[2]))


def _int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    return value
