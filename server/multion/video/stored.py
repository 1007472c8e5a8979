"""What a film is made of and what it gives back, its length cap and its errors: the light half
of :mod:`multion.video`, with no simulator, so that the leaderboard's server process can check
and queue films that a helper process makes (:mod:`.film`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from multion.config.episode import Episode
from multion.config.errors import UsageError
from multion.video.encoder import FPS
from multion_client.constants import Action

FILMED_SENSORS = ("rgb", "depth")
"""What a video shows of the agent's view (metrics do not depend on the sensors)."""
MAX_VIDEO_FRAMES = 6000
"""Longest video: 10 minutes at 10 frames a second (an episode of the paper's 2,500 steps fits
with room for its held frames), at most 37.6 MB (:func:`~.encoder.size_bound`)."""
FOUND_HOLD = 5
END_HOLD = 20


class VideoError(UsageError, ValueError):
    """An episode that cannot be filmed; the message says which and why."""


@dataclass(frozen=True)
class StoredEpisode:
    """What a film is made of: an episode, the actions played in it and the metrics stored."""

    episode: Episode
    actions: tuple[int, ...]
    metrics: dict[str, Any]
    label: str
    """How errors name the episode (an id, or "3 of run …")."""
    title: str
    """The first caption line of every frame (who played what)."""


@dataclass(frozen=True)
class Film:
    """A written video (and its WebVTT captions, where asked for)."""

    path: Path
    frames: int
    seconds: float
    """Time taken to make it (replay, drawing and encoding)."""
    captions: Path | None = None

    @property
    def bytes(self) -> int:
        return self.path.stat().st_size


def frame_count(actions: Sequence[int]) -> int:
    """How many frames the video of ``actions`` has (see :mod:`.film`)."""
    founds = sum(1 for action in actions if action == Action.FOUND)
    return 1 + len(actions) + founds * (FOUND_HOLD - 1) + END_HOLD


def check_length(actions: Sequence[int], label: str) -> None:
    """A VideoError when the video of ``actions`` would be longer than the cap."""
    if (frames := frame_count(actions)) > MAX_VIDEO_FRAMES:
        raise VideoError(
            f"episode {label} would make a video of {frames} frames "
            f"({len(actions)} actions); videos are limited to {MAX_VIDEO_FRAMES} frames "
            f"({MAX_VIDEO_FRAMES // FPS // 60} minutes)"
        )
