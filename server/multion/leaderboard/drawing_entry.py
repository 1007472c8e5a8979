"""Where the picture drawer reaches the simulator: the functions its jobs call in the helper.

A job (:class:`~.web.pictures.EpisodeReplay`, :class:`~.run_videos.EpisodeFilm`) is pickled
by its module and name, so the leaderboard's server process imports this small module and never
the simulator: :mod:`multion.leaderboard.episode_drawing` (and with it PyBullet and the env) is
imported inside each function, in the helper process.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from multion.config.episode import Episode
from multion.video.stored import Film, StoredEpisode


def draw_picture(
    config_dict: dict[str, Any],
    episode: Episode,
    actions: str,
    metrics: dict[str, Any],
    label: str,
    pixels_per_metre: int,
) -> bytes:
    """An episode's picture as a PNG (see :func:`.episode_drawing.draw_picture`)."""
    from multion.leaderboard import episode_drawing  # the helper's import, never the server's

    return episode_drawing.draw_picture(
        config_dict, episode, actions, metrics, label, pixels_per_metre
    )


def film(config_dict: dict[str, Any], stored: StoredEpisode, out: Path, captions: Path) -> Film:
    """An episode's video and captions (see :func:`.episode_drawing.film`)."""
    from multion.leaderboard import episode_drawing

    return episode_drawing.film(config_dict, stored, out, captions)
