"""Filming a stored episode: replay, compose each frame, encode; an MP4 and its captions.

A FOUND's frame is held for ``FOUND_HOLD`` frames and the last frame for ``END_HOLD`` more
(:mod:`.stored`, with the length cap and the film's light types), so
a viewer can read the result: a video of an episode with ``T`` actions, ``F`` of them FOUND, has
``1 + T + F * (FOUND_HOLD - 1) + END_HOLD`` frames at :data:`~.encoder.FPS` frames a second.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from PIL import Image

from multion.common.files import replacing, write_atomically
from multion.task.env import MultiONEnv
from multion.video.captions import CaptionTrack
from multion.video.encoder import FPS, Mp4Writer
from multion.video.frames import FrameComposer
from multion.video.replay import StepView, replay
from multion.video.stored import END_HOLD, FOUND_HOLD, Film, StoredEpisode, VideoError, check_length
from multion_client.constants import Action, goal_categories


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
    Nothing is left at ``out`` or ``captions`` on failure. Both are written through temporary
    files of their own, so two processes filming one episode at once (two replicas of a
    leaderboard, one video folder) each replace it whole."""
    check_length(stored.actions, stored.label)
    started = time.perf_counter()
    track = CaptionTrack(FPS)
    try:
        steps = composed_frames(env, stored)
        view, frame, lines = next(steps)
        with (
            replacing(out) as partial,
            Mp4Writer(partial, frame.shape[1], frame.shape[0]) as writer,
        ):
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
            if captions is not None:  # before the video is in place: it is what readers look for
                write_atomically(captions, track.text())
    except BaseException:
        if captions is not None:
            captions.unlink(missing_ok=True)
        raise
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
