"""Figure 3 style pictures of a run's first episodes, drawn by replaying the stored actions.

Only phases with per-episode feedback (minival) show them, and only the first
:data:`PICTURES_PER_RUN` played episodes of a run: each costs a house build and a replay. They
are drawn once, after the run ended, by :class:`PictureDrawer`: a background task that finds
ended runs without pictures (newest first) and draws them one at a time in a helper process
running at the lowest CPU priority (house building holds the GIL for seconds, and the simulator
workers that step participants' runs must come first). The PNGs are stored in the database, so a
page view only reads them: a burst of picture requests draws nothing.

Pictures are drawn at twice the size they are shown (sharp on high-density screens) and all at
one scale, :data:`PIXELS_PER_METRE`, so text has the same size on every picture.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import io
import logging
import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import exists, or_, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from multion.api.config_io import session_config_from_dict
from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.leaderboard.models import EpisodePicture, EpisodeRecord, Run
from multion.leaderboard.results import RANKED_STATES
from multion.leaderboard.storage import Database
from multion.pictures import episode_picture, gps_to_world
from multion.processes import ignore_stop_signals, limit_address_space
from multion.task.env import MultiONEnv
from multion.task.episode import Episode

log = logging.getLogger("multion.leaderboard.pictures")

PICTURES_PER_RUN = 3
PIXELS_PER_METRE = 80
"""Drawing scale; pages show pictures at half their pixel size (40 CSS px per metre, room
labels and captions 12 CSS px high)."""
DISPLAY_SCALE = 2
DRAWER_MEMORY_BYTES = 3 * 2**30
"""Address-space limit of the drawing process (a house of 16 rooms needs well under a GiB)."""
DRAWER_NICE = 19


def _start_drawer() -> None:
    """In the drawing process: end with the server, yield the CPU to everything else, and
    never take more memory than its limit."""
    ignore_stop_signals()  # a process-group SIGTERM must not end a drawing: the server does
    os.nice(DRAWER_NICE)
    limit_address_space(DRAWER_MEMORY_BYTES)  # or the server's outer limit, if lower


@dataclass(frozen=True)
class EpisodeReplay:
    """What a picture is drawn from: a stored episode of a run, in its track's environment."""

    track: Track
    phase: Phase
    maps: dict[str, Any]
    episode: Episode
    actions: str
    metrics: dict[str, Any]
    label: str

    def draw(self) -> bytes:
        """Replay the actions (GPS only: nothing rendered) and draw the episode as a PNG."""
        config_dict = self.track.env_config(self.phase, ("gps",), self.maps)
        config, _ = session_config_from_dict(config_dict)
        env = MultiONEnv(config, episodes=[self.episode])
        try:
            observation, _ = env.reset(options={"episode_index": 0})
            gps = [np.asarray(observation["gps"], dtype=np.float64)]
            for action in self.actions:
                observation, *_ = env.step(int(action))
                gps.append(np.asarray(observation["gps"], dtype=np.float64))
            path = gps_to_world(np.asarray(gps), self.episode)
            image = episode_picture(
                self.episode, path, self.metrics, env.sim, PIXELS_PER_METRE, label=self.label
            )
        finally:
            env.close()
        buffer = io.BytesIO()
        image.save(buffer, format="PNG", optimize=True)
        return buffer.getvalue()


def pictured(records: Sequence[EpisodeRecord]) -> list[EpisodeRecord]:
    """The episodes of a run that get a picture: its first played ones."""
    return [r for r in records if r.actions][:PICTURES_PER_RUN]


def png_size(png: bytes) -> tuple[int, int]:
    """Width and height of a PNG, from its header."""
    return int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")


def stored_pictures(session: Session, run_id: str) -> dict[int, EpisodePicture]:
    """The run's drawn pictures by episode position (failed drawings left out)."""
    rows = session.scalars(select(EpisodePicture).where(EpisodePicture.run_id == run_id))
    return {p.position: p for p in rows if p.png}


def picture_png(
    session: Session, challenge: Challenge, run_id: str, position: int, now: dt.datetime
) -> bytes | None:
    """One stored picture, if its run's phase shows episodes now (two short reads: the run's
    phase and state, then the picture; never the run's episodes)."""
    found = session.execute(
        select(Run.track, Run.phase, Run.summary.is_not(None)).where(Run.id == run_id)
    ).first()
    if found is None or not found[2]:
        return None
    track = challenge.track(found.track)
    phase = track.phase(found.phase) if track is not None else None
    if phase is None or phase.feedback != "episodes" or not phase.results_visible(now):
        return None
    png = session.scalar(
        select(EpisodePicture.png).where(
            EpisodePicture.run_id == run_id, EpisodePicture.position == position
        )
    )
    return png or None


def runs_without_pictures(session: Session, challenge: Challenge, limit: int = 20) -> list[Run]:
    """Ended runs of phases with per-episode feedback that have no pictures yet, newest first."""
    phases = [
        (track.name, phase.name)
        for track in challenge.tracks
        for phase in track.phases
        if phase.feedback == "episodes"
    ]
    if not phases:
        return []
    drawn = exists().where(EpisodePicture.run_id == Run.id)
    of_phase = [((Run.track == t) & (Run.phase == p)) for t, p in phases]
    query = (
        select(Run)
        .where(Run.state.in_(RANKED_STATES), ~drawn)
        .where(or_(*of_phase))
        .order_by(Run.finished_at.desc())
        .limit(limit)
    )
    return list(session.scalars(query))


EpisodeOf = Callable[[Track, Phase, Run, EpisodeRecord], Episode]
"""The hidden episode a run's stored record played (from the run service's hidden episodes;
blocking: called in a thread)."""


class PictureDrawer:
    """Draws the pictures of ended runs in one low-priority helper process and stores them."""

    def __init__(self, challenge: Challenge, db: Database, episode_of: EpisodeOf) -> None:
        self.challenge, self.db, self.episode_of = challenge, db, episode_of
        self._pool: ProcessPoolExecutor | None = None

    async def draw_forever(self, interval_s: float) -> None:
        while True:
            try:
                drawn = await self.draw_pending()
            except Exception:  # noqa: BLE001 - logged; the next round tries again
                log.exception("drawing run pictures failed")
                drawn = 0
            if drawn == 0:
                await asyncio.sleep(interval_s)

    async def draw_pending(self, limit: int = 1) -> int:
        """Draw the pictures of up to ``limit`` runs that need them; returns how many runs."""
        runs = await asyncio.to_thread(self._pending, limit)
        for run, records in runs:
            await self.draw_run(run, records)
        return len(runs)

    def _pending(self, limit: int) -> list[tuple[Run, list[EpisodeRecord]]]:
        with self.db.sessions() as session:
            found = []
            for run in runs_without_pictures(session, self.challenge, limit):
                records = session.scalars(
                    select(EpisodeRecord)
                    .where(EpisodeRecord.run_id == run.id, EpisodeRecord.actions != "")
                    .order_by(EpisodeRecord.position)
                    .limit(PICTURES_PER_RUN)
                )
                found.append((run, list(records)))
            return found

    async def draw_run(self, run: Run, records: Sequence[EpisodeRecord]) -> None:
        track = self.challenge.track(run.track)
        phase = track.phase(run.phase) if track is not None else None
        if track is None or phase is None:
            return
        pictures = []
        for record in pictured(records):
            episode = await asyncio.to_thread(self.episode_of, track, phase, run, record)
            replay = EpisodeReplay(
                track, phase, dict(run.maps or {}), episode,
                record.actions, record.metrics, f"episode {record.position + 1}",
            )  # fmt: skip
            try:
                png = await self._draw(replay)
            except Exception:  # noqa: BLE001 - recorded as failed, never retried in a loop
                log.exception("the picture of episode %d of run %s failed", record.position, run.id)
                png = b""
            width, height = png_size(png) if png else (0, 0)
            pictures.append(EpisodePicture(
                run_id=run.id, position=record.position, png=png, width=width, height=height
            ))  # fmt: skip
        if not pictures:  # nothing played: an empty marker so the run is not looked at again
            pictures.append(EpisodePicture(run_id=run.id, position=-1, png=b"", width=0, height=0))
        await asyncio.to_thread(self._store, pictures)

    def _store(self, pictures: list[EpisodePicture]) -> None:
        try:
            with self.db.sessions.begin() as session:
                session.add_all(pictures)
        except IntegrityError:  # another replica drew them first
            pass

    async def _draw(self, replay: EpisodeReplay) -> bytes:
        """Draw in the helper process; a helper that died (a broken pool stays broken) is
        replaced by a new one, which tries once more."""
        for attempt in range(2):
            pool = self._executor()
            try:
                return await asyncio.wrap_future(pool.submit(replay.draw))
            except BrokenProcessPool:
                log.warning("the picture drawer died; starting a new one")
                if self._pool is pool:
                    self._pool = None
                pool.shutdown(wait=False, cancel_futures=True)
                if attempt == 1:
                    raise
        raise AssertionError("unreachable")

    def _executor(self) -> ProcessPoolExecutor:
        if self._pool is None:
            spawn = multiprocessing.get_context("spawn")
            self._pool = ProcessPoolExecutor(1, spawn, initializer=_start_drawer)
        return self._pool

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
