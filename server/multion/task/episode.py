"""Episodes: a scene, a start pose and an ordered list of goals (SPEC §5)."""

from __future__ import annotations

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
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Episode:
        """Build from the JSON form; raises ``ValueError``/``KeyError``/``TypeError`` on bad data."""
        return cls(
            episode_id=str(data["episode_id"]),
            scene_id=str(data["scene_id"]),
            start_position=_point(data["start_position"], "start_position"),
            start_yaw=float(data["start_yaw"]),
            goals=tuple(
                Goal(
                    category=_int(g["category"], "category"),
                    position=_point(g["position"], "goal position"),
                )
                for g in data["goals"]
            ),
            geodesic_distances=tuple(float(d) for d in data.get("geodesic_distances", ())),
        )


def _point(value: Any, name: str) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise ValueError(f"{name} must be a list of 3 numbers, got {value!r}")
    return (float(value[0]), float(value[1]), float(value[2]))


def _int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    return value
