"""Filming a stored episode: replay, compose each frame, encode; an MP4 and its captions.

A FOUND's frame is held for ``FOUND_HOLD`` frames and the last frame for ``END_HOLD`` more, so
a viewer can read the result: a video of an episode with ``T`` actions, ``F`` of them FOUND, has
``1 + T + F * (FOUND_HOLD - 1) + END_HOLD`` frames at :data:`~.encoder.FPS` frames a second.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from multion.config.episode import Episode
from multion.task.env import MultiONEnv
from multion.video.captions import CaptionTrack
from multion.video.encoder import FPS, Mp4Writer
from multion.video.frames import FrameComposer
from multion.video.replay import StepView, VideoError, replay
from multion_client.constants import Action, goal_categories

MAX_VIDEO_FRAMES = 6000
"""Longest video: 10 minutes at 10 frames a second (an episode of the paper's 2,500 steps fits
with room for its held frames), at most 37.6 MB (:func:`~.encoder.size_bound`)."""
FOUND_HOLD = 5
END_HOLD = 20


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
    """How many frames the video of ``actions`` has (see the module docstring)."""
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


def composed_frames(
    env: MultiONEnv, stored: StoredEpisode
) -> Iterator[tuple[StepView, np.ndarray, tuple[str, str]]]:
    """Each replayed step of ``stored``, its frame and its caption lines (status, event); a
    VideoError at the end when the replay does not reproduce the stored metrics."""
    views = replay(env, stored.episode, stored.actions, stored.metrics, stored.label)
    first = next(views)
    assert env.sim.grid is not None, "replay() resets the environment"
    camera, task = env.config.camera, env.config.task
    composer = FrameComposer(
        stored.episode,
        env.sim.grid,
        (camera.width, camera.height),
        stored.title,
        goal_categories(task.goal_set),
        task.max_steps,
        depth_scale=1.0 if camera.normalize_depth else 1.0 / camera.max_depth,
    )
    for view in itertools.chain([first], views):
        yield view, composer.frame(view), (composer.status(view), composer.event(view)[0])


def film_episode(
    env: MultiONEnv, stored: StoredEpisode, out: Path, captions: Path | None = None
) -> Film:
    """Write the video of ``stored`` to ``out`` (and its WebVTT captions to ``captions``),
    replayed in ``env`` (any config of the episode's track with :data:`FILMED_SENSORS`).
    Nothing is left at ``out`` or ``captions`` on failure."""
    check_length(stored.actions, stored.label)
    started = time.perf_counter()
    partial = out.with_name(out.name + ".partial")
    track = CaptionTrack(FPS)
    try:
        steps = composed_frames(env, stored)
        view, frame, lines = next(steps)
        with Mp4Writer(partial, frame.shape[1], frame.shape[0]) as writer:
            writer.write(frame)
            track.add(0, 1, (stored.title, *lines))  # the first cue says what is shown
            for view, frame, lines in steps:
                hold = FOUND_HOLD if view.action == Action.FOUND else 1
                track.add(writer.frames, hold, lines)
                for _ in range(hold):
                    writer.write(frame)
            track.add(writer.frames, END_HOLD, lines)
            for _ in range(END_HOLD):
                writer.write(frame)
            frames = writer.frames
        if captions is not None:
            captions.write_text(track.text(), encoding="utf-8")
        partial.replace(out)
    except BaseException:
        if captions is not None:
            captions.unlink(missing_ok=True)
        raise
    finally:
        partial.unlink(missing_ok=True)
    return Film(out, frames, time.perf_counter() - started, captions)


def still(env: MultiONEnv, stored: StoredEpisode, step: int) -> Image.Image:
    """The frame of ``step`` (0: the start) as a picture, for slides and docs; the whole
    episode is replayed, so its metrics are checked as for a video."""
    if not 0 <= step <= len(stored.actions):
        raise VideoError(
            f"--still must be a step in [0, {len(stored.actions)}] of episode "
            f"{stored.label}, got {step}"
        )
    chosen = None
    for view, frame, _ in composed_frames(env, stored):
        if view.step == step:
            chosen = frame
    assert chosen is not None
    return Image.fromarray(chosen)
