"""The simulator's half of a run page's pictures and films: a stored episode played again.

Imported only through :mod:`multion.leaderboard.drawing_entry`, inside the picture drawer's
helper process (or the organiser's command): the leaderboard's server process never loads the
simulator. Its callers (:mod:`.web.pictures`, :mod:`.run_videos`) pass plain values: the
environment's config as a dict, the episode and what was stored of it.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from multion.config.codec import session_config_from_dict
from multion.config.episode import Episode
from multion.scenes.viz import gps_to_world
from multion.sim.pictures import episode_picture
from multion.task.env import MultiONEnv
from multion.video.film import film_episode
from multion.video.stored import Film, StoredEpisode


def draw_picture(
    config_dict: dict[str, Any],
    episode: Episode,
    actions: str,
    metrics: dict[str, Any],
    label: str,
    pixels_per_metre: int,
) -> bytes:
    """Replay ``actions`` (GPS only: nothing rendered) and draw the episode as a PNG."""
    config, _ = session_config_from_dict(config_dict)
    env = MultiONEnv(config, episodes=[episode])
    try:
        observation, _ = env.reset(options={"episode_index": 0})
        gps = [np.asarray(observation["gps"], dtype=np.float64)]
        for action in actions:
            observation, *_ = env.step(int(action))
            gps.append(np.asarray(observation["gps"], dtype=np.float64))
        path = gps_to_world(np.asarray(gps), episode)
        image = episode_picture(episode, path, metrics, env.sim, pixels_per_metre, label=label)
    finally:
        env.close()
    buffer = io.BytesIO()
    image.save(buffer, format="PNG", optimize=True)
    return buffer.getvalue()


def film(config_dict: dict[str, Any], stored: StoredEpisode, out: Path, captions: Path) -> Film:
    """Film ``stored`` in an environment of ``config_dict`` (:data:`FILMED_SENSORS`)."""
    config, _ = session_config_from_dict(config_dict)
    env = MultiONEnv(config, episodes=[])
    try:
        return film_episode(env, stored, out, captions)
    finally:
        env.close()
