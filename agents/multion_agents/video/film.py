"""Filming the episodes of a ``multion eval`` run directory: one MP4 per episode.

The replay, the frames and the encoding are :mod:`multion.video`'s (the leaderboard films its
runs with the same code); this module names the run's episodes and where their videos go.
"""

from __future__ import annotations

from pathlib import Path

from PIL import Image

from multion.task.env import MultiONEnv
from multion.video.film import film_episode as film_stored
from multion.video.film import still as still_of
from multion.video.stored import Film, StoredEpisode, check_length
from multion_agents.video.recorded import (
    RecordedEpisode,
    RecordedRun,
    VideoError,
    dataset_episode,
    replay_env,
)

MAX_VIDEOS = 100
"""``multion eval --video N``: N at most this (each video replays its episode: seconds each)."""


def video_name(episode_id: str) -> str:
    return f"episode-{episode_id}.mp4"


def stored_episode(run: RecordedRun, recorded: RecordedEpisode) -> StoredEpisode:
    """What :mod:`multion.video.film` films of a recorded episode (its length checked first)."""
    check_length(recorded.actions, recorded.episode_id)
    episode = dataset_episode(run, recorded.episode_id)
    return StoredEpisode(
        episode,
        recorded.actions,
        recorded.metrics,
        recorded.episode_id,
        f"{run.agent} · {episode.episode_id} · {episode.scene_id}",
    )


def film_episode(
    run: RecordedRun, recorded: RecordedEpisode, out: Path, env: MultiONEnv | None = None
) -> Film:
    """Write the video of ``recorded`` to ``out``; ``env`` (from :func:`replay_env`) may be
    reused between episodes of one run. Nothing is left at ``out`` on failure."""
    stored = stored_episode(run, recorded)
    own = env is None
    env = env or replay_env(run)
    try:
        return film_stored(env, stored, out)
    finally:
        if own:
            env.close()


def still(run: RecordedRun, recorded: RecordedEpisode, step: int) -> Image.Image:
    """The frame of ``step`` (0: the start) as a picture, for slides and docs; the whole
    episode is replayed, so its metrics are checked as for a video."""
    stored = stored_episode(run, recorded)
    env = replay_env(run)
    try:
        return still_of(env, stored, step)
    finally:
        env.close()


def film_run(run: RecordedRun, count: int, out_dir: Path | None = None) -> list[Film]:
    """Videos of the run's first ``count`` episodes (in evaluation order), named
    ``episode-<id>.mp4`` in ``out_dir`` (the run's directory by default)."""
    if not 0 <= count <= MAX_VIDEOS:
        raise VideoError(f"--video must be in [0, {MAX_VIDEOS}], got {count}")
    chosen = sorted(run.episodes, key=lambda e: e.index)[:count]
    if not chosen:
        return []
    env = replay_env(run)
    try:
        return [
            film_episode(run, e, (out_dir or run.path) / video_name(e.episode_id), env)
            for e in chosen
        ]
    finally:
        env.close()
