"""Filming recorded episodes: replay, compose each frame, encode; one MP4 per episode.

A FOUND's frame is held for ``FOUND_HOLD`` frames and the last frame for ``END_HOLD`` more, so
a viewer can read the result: a video of an episode with ``T`` actions, ``F`` of them FOUND, has
``1 + T + F * (FOUND_HOLD - 1) + END_HOLD`` frames at :data:`~.encoder.FPS` frames a second.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from multion.sim.navgrid import NavGrid
from multion.task.env import MultiONEnv
from multion_agents.video.encoder import FPS, Mp4Writer
from multion_agents.video.frames import FrameComposer
from multion_agents.video.recorded import (
    RecordedEpisode,
    RecordedRun,
    StepView,
    VideoError,
    dataset_episode,
    replay,
    replay_env,
)
from multion_client.constants import Action, goal_categories

MAX_VIDEOS = 100
"""``multion eval --video N``: N at most this (each video replays its episode: seconds each)."""
MAX_VIDEO_FRAMES = 6000
"""Longest video: 10 minutes at 10 frames a second (an episode of the paper's 2,500 steps fits
with room for its held frames), at most 37.6 MB (:func:`~.encoder.size_bound`)."""
FOUND_HOLD = 5
END_HOLD = 20


@dataclass(frozen=True)
class Film:
    """A written video."""

    path: Path
    frames: int
    seconds: float
    """Time taken to make it (replay, drawing and encoding)."""

    @property
    def bytes(self) -> int:
        return self.path.stat().st_size


def frame_count(actions: Sequence[int]) -> int:
    """How many frames the video of ``actions`` has (see the module docstring)."""
    founds = sum(1 for action in actions if action == Action.FOUND)
    return 1 + len(actions) + founds * (FOUND_HOLD - 1) + END_HOLD


def video_name(episode_id: str) -> str:
    return f"episode-{episode_id}.mp4"


def composed_frames(
    run: RecordedRun, recorded: RecordedEpisode, env: MultiONEnv
) -> Iterator[tuple[StepView, np.ndarray]]:
    """Each replayed step of ``recorded`` and its frame (a VideoError at the end when the replay
    does not reproduce the recorded metrics)."""
    episode = dataset_episode(run, recorded.episode_id)
    views = replay(env, episode, recorded)
    first = next(views)
    camera, task = env.config.camera, env.config.task
    composer = FrameComposer(
        episode,
        _grid(env),
        (camera.width, camera.height),
        f"{run.agent} · {episode.episode_id} · {episode.scene_id}",
        goal_categories(task.goal_set),
        task.max_steps,
        depth_scale=1.0 if camera.normalize_depth else 1.0 / camera.max_depth,
    )
    yield first, composer.frame(first)
    for view in views:
        yield view, composer.frame(view)


def film_episode(
    run: RecordedRun, recorded: RecordedEpisode, out: Path, env: MultiONEnv | None = None
) -> Film:
    """Write the video of ``recorded`` to ``out``; ``env`` (from :func:`replay_env`) may be
    reused between episodes of one run. Nothing is left at ``out`` on failure."""
    if (frames := frame_count(recorded.actions)) > MAX_VIDEO_FRAMES:
        raise VideoError(
            f"episode {recorded.episode_id} would make a video of {frames} frames "
            f"({len(recorded.actions)} actions); videos are limited to {MAX_VIDEO_FRAMES} frames "
            f"({MAX_VIDEO_FRAMES // FPS // 60} minutes)"
        )
    started = time.perf_counter()
    own = env is None
    env = env or replay_env(run)
    partial = out.with_name(out.name + ".partial")
    try:
        steps = composed_frames(run, recorded, env)
        _, frame = next(steps)
        with Mp4Writer(partial, frame.shape[1], frame.shape[0]) as writer:
            writer.write(frame)
            for view, frame in steps:
                for _ in range(FOUND_HOLD if view.action == Action.FOUND else 1):
                    writer.write(frame)
            for _ in range(END_HOLD):
                writer.write(frame)
            frames = writer.frames
        partial.replace(out)
    finally:
        partial.unlink(missing_ok=True)
        if own:
            env.close()
    return Film(out, frames, time.perf_counter() - started)


def still(run: RecordedRun, recorded: RecordedEpisode, step: int) -> Image.Image:
    """The frame of ``step`` (0: the start) as a picture, for slides and docs; the whole
    episode is replayed, so its metrics are checked as for a video."""
    if not 0 <= step <= len(recorded.actions):
        raise VideoError(
            f"--still must be a step in [0, {len(recorded.actions)}] of episode "
            f"{recorded.episode_id}, got {step}"
        )
    env = replay_env(run)
    try:
        chosen = None
        for view, frame in composed_frames(run, recorded, env):
            if view.step == step:
                chosen = frame
    finally:
        env.close()
    assert chosen is not None
    return Image.fromarray(chosen)


def _grid(env: MultiONEnv) -> NavGrid:
    assert env.sim.grid is not None, "reset the environment first"
    return env.sim.grid


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
