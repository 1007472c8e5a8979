"""Figure 3 style pictures of a run's first episodes, drawn by replaying the stored actions.

Only phases with per-episode feedback (minival) show them, and only the first
:data:`PICTURES_PER_RUN` played episodes of a run: each costs a house build and a replay. They
are drawn once, after the run ended, by :class:`PictureDrawer`: a background task that finds
ended runs without pictures (newest first), claims one (replicas share the work) and draws its
pictures in a helper process running at the lowest CPU priority (house building holds the GIL
for seconds, and the simulator workers that step participants' runs must come first); a
picture that failed is tried again later. The PNGs are stored in the database, so a page view
only reads them: a burst of picture requests draws nothing.

Pictures are drawn at twice the size they are shown (sharp on high-density screens) and all at
one scale, :data:`PIXELS_PER_METRE`, so text has the same size on every picture.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import logging
import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any, TypeVar, cast

from sqlalchemy import CursorResult, Insert, Select, delete, exists, or_, select, update
from sqlalchemy.orm import Session

from multion.common.processes import ignore_stop_signals, limit_address_space
from multion.config.episode import Episode
from multion.leaderboard import drawing_entry
from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.leaderboard.models import EpisodePicture, EpisodeRecord, Run, utcnow
from multion.leaderboard.results import RANKED_STATES
from multion.leaderboard.storage import Database

log = logging.getLogger("multion.leaderboard.pictures")
Drawn = TypeVar("Drawn")

PICTURES_PER_RUN = 3
PIXELS_PER_METRE = 80
"""Drawing scale; pages show pictures at half their pixel size (40 CSS px per metre, room
labels and captions 12 CSS px high)."""
DISPLAY_SCALE = 2
DRAWER_MEMORY_BYTES = 3 * 2**30
"""Address-space limit of the drawing process (a house of 16 rooms needs well under a GiB)."""
DRAWER_NICE = 19
CLAIM = -2
"""Position of a run's claim row: ``created_at`` is when the claim lapses (the lease of the
replica drawing it, or the time of the next try after a failure), ``width`` the failed tries."""
NOTHING = -1
"""Position of the marker of a run that had nothing to draw (no episode played)."""
LEASE = dt.timedelta(minutes=10)
MAX_ATTEMPTS = 3
"""Tries of a picture that fails to draw; then it is stored empty and its page says so."""


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
        """Replay the actions (GPS only: nothing rendered) and draw the episode as a PNG, in
        this process (the drawer's helper: it loads the simulator)."""
        config_dict = self.track.env_config(self.phase, ("gps",), self.maps)
        return drawing_entry.draw_picture(
            config_dict, self.episode, self.actions, self.metrics, self.label, PIXELS_PER_METRE
        )


def pictured(records: Sequence[EpisodeRecord]) -> list[EpisodeRecord]:
    """The episodes of a run that get a picture: its first played ones."""
    return [r for r in records if r.actions][:PICTURES_PER_RUN]


def png_size(png: bytes) -> tuple[int, int]:
    """Width and height of a PNG, from its header."""
    return int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")


def stored_pictures(session: Session, run_id: str) -> dict[int, EpisodePicture]:
    """The run's pictures by episode position; an empty ``png``: given up after
    :data:`MAX_ATTEMPTS` failed drawings (a missing one is still to be drawn)."""
    rows = session.scalars(
        select(EpisodePicture).where(EpisodePicture.run_id == run_id, EpisodePicture.position >= 0)
    )
    return {p.position: p for p in rows}


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


def runs_needing_pictures(
    session: Session, challenge: Challenge, now: dt.datetime, limit: int = 20
) -> list[Run]:
    """Ended runs of phases with per-episode feedback, newest first, that were never looked at
    (no picture row) or whose claim is due: a failed drawing's retry time, or the lease of a
    replica that died while drawing."""
    phases = [
        (track.name, phase.name)
        for track in challenge.tracks
        for phase in track.phases
        if phase.feedback == "episodes"
    ]
    if not phases:
        return []
    seen = exists().where(EpisodePicture.run_id == Run.id)
    due = exists().where(
        EpisodePicture.run_id == Run.id,
        EpisodePicture.position == CLAIM,
        EpisodePicture.created_at <= now,
    )
    of_phase = [((Run.track == t) & (Run.phase == p)) for t, p in phases]
    query = (
        select(Run)
        .where(Run.state.in_(RANKED_STATES), or_(~seen, due))
        .where(or_(*of_phase))
        .order_by(Run.finished_at.desc())
        .limit(limit)
    )
    return list(session.scalars(query))


EpisodeOf = Callable[[Track, Phase, Run, EpisodeRecord], Episode]
"""The hidden episode a run's stored record played (from the run service's hidden episodes;
blocking: called in a thread)."""


class PictureDrawer:
    """Draws the pictures of ended runs in one low-priority helper process and stores them.

    Several replicas may share the database: a replica draws a run only after claiming it
    (one row inserted if absent, or a lapsed claim taken over: never a duplicate key), and a
    picture that failed to draw is tried again later, up to :data:`MAX_ATTEMPTS` times."""

    def __init__(
        self, challenge: Challenge, db: Database, episode_of: EpisodeOf, retry_s: float = 60.0
    ) -> None:
        self.challenge, self.db, self.episode_of = challenge, db, episode_of
        self.retry_s = retry_s
        """Wait before the next try of a failed picture (times the tries so far)."""
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
        """Draw the pictures of up to ``limit`` runs that need them and that this replica
        could claim; returns how many runs."""
        runs = await asyncio.to_thread(self._pending, limit)
        for run, records, tries, drawn in runs:
            await self.draw_run(run, records, tries, drawn)
        return len(runs)

    def _pending(self, limit: int) -> list[tuple[Run, list[EpisodeRecord], int, set[int]]]:
        found = []
        with self.db.sessions() as session:
            candidates = runs_needing_pictures(session, self.challenge, utcnow(), limit)
        for run in candidates:
            tries = self._claim(run.id)
            if tries is None:
                continue  # another replica has it
            with self.db.sessions() as session:
                records = session.scalars(
                    select(EpisodeRecord)
                    .where(EpisodeRecord.run_id == run.id, EpisodeRecord.actions != "")
                    .order_by(EpisodeRecord.position)
                    .limit(PICTURES_PER_RUN)
                )
                drawn = set(stored_pictures(session, run.id))
                found.append((run, list(records), tries, drawn))
        return found

    def _claim(self, run_id: str) -> int | None:
        """Claim a run's drawing for :data:`LEASE`: its failed tries so far, or None when
        another replica holds it (or drew it meanwhile)."""
        now = utcnow()
        with self.db.sessions.begin() as session:
            # execute() is typed as returning a Result; an UPDATE's is a CursorResult (rowcount)
            claimed = cast(CursorResult[Any], session.execute(
                update(EpisodePicture)
                .where(EpisodePicture.run_id == run_id, EpisodePicture.position == CLAIM,
                       EpisodePicture.created_at <= now)
                .values(created_at=now + LEASE)
            ))  # fmt: skip
            taken = claimed.rowcount
            if taken == 1:  # a lapsed claim: a retry after a failure, or a replica died
                return int(session.scalar(_claim_column(run_id, EpisodePicture.width)) or 0)
            if session.scalar(select(exists().where(EpisodePicture.run_id == run_id))):
                return None
            inserted = _insert_new(session, [_row(run_id, CLAIM, now + LEASE)])
            return 0 if inserted else None

    async def draw_run(
        self, run: Run, records: Sequence[EpisodeRecord], tries: int = 0,
        drawn: set[int] | None = None,
    ) -> None:  # fmt: skip
        """Draw the run's pictures not drawn yet and store them; a failure is tried again
        after ``retry_s × tries`` until :data:`MAX_ATTEMPTS`, then stored empty."""
        track = self.challenge.track(run.track)
        phase = track.phase(run.phase) if track is not None else None
        if track is None or phase is None:
            return
        pictures, failed = [], []
        for record in pictured(records):
            if record.position in (drawn or set()):
                continue
            try:
                episode = await asyncio.to_thread(self.episode_of, track, phase, run, record)
                replay = EpisodeReplay(
                    track, phase, dict(run.maps or {}), episode,
                    record.actions, record.metrics, f"episode {record.position + 1}",
                )  # fmt: skip
                png = await self._draw(replay)
            except Exception:  # noqa: BLE001 - tried again later (MAX_ATTEMPTS in all)
                log.exception("the picture of episode %d of run %s failed (try %d of %d)",
                              record.position, run.id, tries + 1, MAX_ATTEMPTS)  # fmt: skip
                failed.append(record.position)
                continue
            width, height = png_size(png)
            pictures.append(_row(run.id, record.position, utcnow(), png, width, height))
        await asyncio.to_thread(self._store, run.id, pictures, failed, tries + 1)

    def _store(
        self, run_id: str, pictures: list[dict[str, Any]], failed: list[int], tries: int
    ) -> None:
        """Store what was drawn; on failures, give up after :data:`MAX_ATTEMPTS` tries or let
        the claim lapse when the next try is due; else drop the claim (the run is done)."""
        now = utcnow()
        with self.db.sessions.begin() as session:
            if failed and tries >= MAX_ATTEMPTS:  # given up: the page says it failed
                pictures += [_row(run_id, position, now) for position in failed]
                failed = []
            _insert_new(session, pictures)
            if failed:  # the claim lapses when the next try is due
                retry = now + dt.timedelta(seconds=self.retry_s * tries)
                session.execute(
                    update(EpisodePicture)
                    .where(EpisodePicture.run_id == run_id, EpisodePicture.position == CLAIM)
                    .values(created_at=retry, width=tries)
                )
                return
            session.execute(
                delete(EpisodePicture).where(
                    EpisodePicture.run_id == run_id, EpisodePicture.position == CLAIM
                )
            )
            if not session.scalar(select(exists().where(EpisodePicture.run_id == run_id))):
                _insert_new(session, [_row(run_id, NOTHING, now)])  # nothing played

    async def _draw(self, replay: EpisodeReplay) -> bytes:
        return await self.in_helper(replay.draw)

    async def in_helper(self, work: Callable[[], Drawn]) -> Drawn:
        """Run ``work`` (picklable) in the helper process (pictures, and the run pages'
        videos); a helper that died (a broken pool stays broken) is replaced by a new one,
        which tries once more."""
        for attempt in range(2):
            pool = self._executor()
            try:
                return await asyncio.wrap_future(pool.submit(work))
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


def _row(
    run_id: str, position: int, created_at: dt.datetime, png: bytes = b"", width: int = 0,
    height: int = 0,
) -> dict[str, Any]:  # fmt: skip
    """An ``episode_pictures`` row: a picture, an empty one (given up), a claim or a marker."""
    return {"run_id": run_id, "position": position, "png": png, "width": width,
            "height": height, "created_at": created_at}  # fmt: skip


def _claim_column(run_id: str, column: Any) -> Select[Any]:
    return select(column).where(EpisodePicture.run_id == run_id, EpisodePicture.position == CLAIM)


def _insert_new(session: Session, rows: list[dict[str, Any]]) -> int:
    """Insert the picture rows whose (run, position) is absent; returns how many were new.
    ON CONFLICT DO NOTHING: a row another replica wrote first is no error (nor a duplicate-key
    line in PostgreSQL's log)."""
    if not rows:
        return 0
    dialect = session.get_bind().dialect.name
    key = ["run_id", "position"]
    statement: Insert  # each dialect has its own Insert class with ON CONFLICT
    if dialect == "postgresql":
        from sqlalchemy.dialects import postgresql

        statement = postgresql.insert(EpisodePicture).on_conflict_do_nothing(index_elements=key)
    elif dialect == "sqlite":
        from sqlalchemy.dialects import sqlite

        statement = sqlite.insert(EpisodePicture).on_conflict_do_nothing(index_elements=key)
    else:  # pragma: no cover - the two databases the leaderboard supports
        raise NotImplementedError(f"pictures need PostgreSQL or SQLite, not {dialect}")
    # RETURNING, not rowcount: the PostgreSQL driver reports no rowcount for an INSERT (-1)
    returning = statement.returning(EpisodePicture.position)
    return sum(len(session.execute(returning.values(**row)).all()) for row in rows)
