"""Episode videos of the run pages: filmed in the picture drawer's process, cached on disk.

After a run of a phase with per-episode feedback ends, :meth:`VideoFilmer.film_forever` films
the episodes that have pictures (its first played ones) in the background; a request for any
other played episode's video (or one evicted from the cache) starts its filming and is answered
"try again shortly". Films are kept in a directory (one per replica) of at most
``video_cache_mib``; the least recently watched are removed first. A page view films nothing.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import hashlib
import logging
import re
import tempfile
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path

from sqlalchemy import select

from multion.leaderboard.challenge import Challenge
from multion.leaderboard.models import EpisodeRecord, Run, utcnow
from multion.leaderboard.results import RANKED_STATES
from multion.leaderboard.run_videos import EpisodeFilm, Refusal, episode_film, video_refusal
from multion.leaderboard.storage import Database
from multion.leaderboard.web.pictures import EpisodeOf, pictured
from multion.video.encoder import EncoderUnavailable, check_encoder
from multion.video.stored import Film

log = logging.getLogger("multion.leaderboard.videos")

FILM_FORMAT = "v1"
"""Part of each cached file's name: a change to the frames' drawing changes it, so old films
are not served (and age out of the cache)."""
SAFE_RUN_ID = re.compile(r"[A-Za-z0-9_-]{1,80}")
MAX_PENDING = 8
"""Films queued at most at once (requests beyond it are told to try again later)."""
RECENT_RUNS = 20
"""The background looks at this many of the newest ended runs for films to make."""


def default_video_dir(database: str) -> Path:
    """Where a server keeps its films when not told: a temporary folder of its database."""
    digest = hashlib.sha256(database.encode()).hexdigest()[:12]
    return Path(tempfile.gettempdir()) / f"multion-leaderboard-videos-{digest}"


@dataclass(frozen=True)
class VideoState:
    """What the run page shows of one episode's video."""

    record: EpisodeRecord
    ready: bool
    note: str
    """Why there is no video (yet), or ''."""


class VideoCache:
    """Films and captions by run and episode position, at most ``max_bytes`` in all."""

    def __init__(self, directory: Path, max_bytes: int) -> None:
        self.directory, self.max_bytes = directory, max_bytes

    def paths(self, run_id: str, position: int) -> tuple[Path, Path]:
        """The MP4 and WebVTT files (run ids are checked to be plain names first)."""
        if not SAFE_RUN_ID.fullmatch(run_id):
            raise ValueError(f"not a run id: {run_id!r}")
        stem = self.directory / run_id / f"episode-{position}-{FILM_FORMAT}"
        return stem.with_suffix(".mp4"), stem.with_suffix(".vtt")

    def ready(self, run_id: str, position: int) -> bool:
        return all(path.is_file() for path in self.paths(run_id, position))

    def watched(self, run_id: str, position: int) -> None:
        """Mark a film as just watched: the last to be evicted. The mark is a separate empty
        file's time (shared by a replica's workers): the film's and captions' own modification
        times stay those of their filming, so their ETag and Last-Modified stay the same."""
        video, _ = self.paths(run_id, position)
        try:
            watched_mark(video).touch()
        except FileNotFoundError:  # the run's folder was removed meanwhile
            pass

    def evict(self) -> int:
        """Remove the least recently watched films until the rest fit; returns how many."""
        films = []
        for video in self.directory.glob("*/episode-*.mp4"):
            try:
                stat = video.stat()
            except FileNotFoundError:
                continue
            captions, mark = video.with_suffix(".vtt"), watched_mark(video)
            size = stat.st_size + (captions.stat().st_size if captions.is_file() else 0)
            try:  # watched last then, or (never watched) filmed then
                last = max(stat.st_mtime, mark.stat().st_mtime)
            except FileNotFoundError:
                last = stat.st_mtime
            films.append((last, size, video, captions, mark))
        total = sum(film[1] for film in films)
        removed = 0
        for _, size, video, captions, mark in sorted(films, key=lambda film: film[0]):
            if total <= self.max_bytes:
                break
            for path in (video, captions, mark):
                path.unlink(missing_ok=True)
            total, removed = total - size, removed + 1
        return removed


def watched_mark(video: Path) -> Path:
    """The empty file whose modification time says when ``video`` was last watched."""
    return video.with_suffix(".watched")


InHelper = Callable[[Callable[[], Film]], Awaitable[Film]]
"""Runs a film in the picture drawer's low-priority process."""


class VideoFilmer:
    """Films episodes in the background, one at a time, and remembers what failed."""

    def __init__(
        self, challenge: Challenge, db: Database, cache: VideoCache, episode_of: EpisodeOf,
        in_helper: InHelper,
    ) -> None:  # fmt: skip
        self.challenge, self.db, self.cache = challenge, db, cache
        self.episode_of, self.in_helper = episode_of, in_helper
        self.pending: dict[tuple[str, int], asyncio.Task[None]] = {}
        self.failed: dict[tuple[str, int], str] = {}
        self.filmed = 0
        """Films made by this server (a cached film is never made again)."""
        self._one_at_a_time = asyncio.Lock()
        self.unavailable = encoder_missing()

    # ------------------------------------------------------------------ asking for a film
    def state(self, run_id: str, record: EpisodeRecord) -> VideoState:
        """Ready, being filmed, failed, or not filmed yet (the page says which)."""
        key = (run_id, record.position)
        if self.unavailable:
            return VideoState(record, False, self.unavailable)
        if self.cache.ready(*key):
            return VideoState(record, True, "")
        if key in self.failed:
            return VideoState(record, False, f"This video could not be made: {self.failed[key]}")
        return VideoState(record, False, "The video is being made: reload in a minute.")

    def request(self, run: Run, record: EpisodeRecord) -> bool:
        """Start filming ``record`` unless it is filmed, failed or queued; False when the
        queue is full."""
        key = (run.id, record.position)
        if key in self.pending or key in self.failed or self.cache.ready(*key):
            return True
        if len(self.pending) >= MAX_PENDING:
            return False
        self.pending[key] = asyncio.create_task(self._film(run, record))
        return True

    async def _film(self, run: Run, record: EpisodeRecord) -> None:
        key = (run.id, record.position)
        try:
            async with self._one_at_a_time:  # one film at a time: the helper is one process
                if self.cache.ready(*key):
                    return
                track = self.challenge.track(run.track)
                phase = track.phase(run.phase) if track is not None else None
                assert track is not None and phase is not None, "checked by video_refusal"
                episode = await asyncio.to_thread(self.episode_of, track, phase, run, record)
                out, captions = self.cache.paths(*key)
                out.parent.mkdir(parents=True, exist_ok=True)
                job: EpisodeFilm = episode_film(track, phase, run, record, episode, out, captions)
                film = await self.in_helper(job.film)
                self.filmed += 1
                log.info("filmed episode %d of run %s: %d frames, %.1f s", record.position,
                         run.id, film.frames, film.seconds)  # fmt: skip
                await asyncio.to_thread(self.cache.evict)
        except ValueError as error:  # a VideoError: the replay is not the stored episode
            log.warning("episode %d of run %s cannot be filmed: %s", *key[::-1], error)
            self.failed[key] = str(error)
        except Exception:  # noqa: BLE001 - logged; the page says it failed
            log.exception("filming episode %d of run %s failed", *key[::-1])
            self.failed[key] = "the server could not film it (its log says why)"
        finally:
            self.pending.pop(key, None)

    # ------------------------------------------------------------------ the background
    async def film_forever(self, interval_s: float) -> None:
        """Film the pictured episodes of newly ended runs (each once per server)."""
        if self.unavailable:
            log.warning("episode videos are off: %s", self.unavailable)
            return
        while True:
            try:
                for run, record in await asyncio.to_thread(self.wanted):
                    self.request(run, record)
                await asyncio.gather(*list(self.pending.values()))
            except Exception:  # noqa: BLE001 - logged; the next round tries again
                log.exception("filming run videos failed")
            await asyncio.sleep(interval_s)

    def wanted(self) -> list[tuple[Run, EpisodeRecord]]:
        """The pictured episodes of the newest ended runs that have no film and may show one."""
        now, found = utcnow(), []
        with self.db.sessions() as session:
            runs = session.scalars(
                select(Run).where(Run.state.in_(RANKED_STATES)).order_by(Run.finished_at.desc())
                .limit(RECENT_RUNS)
            )  # fmt: skip
            for run in runs:
                records = session.scalars(
                    select(EpisodeRecord).where(EpisodeRecord.run_id == run.id)
                    .order_by(EpisodeRecord.position)
                )  # fmt: skip
                for record in pictured(list(records)):
                    key = (run.id, record.position)
                    if key in self.failed or self.cache.ready(*key):
                        continue
                    if refusal_of(self.challenge, run, record, now) is None:
                        found.append((run, record))
        return found


def refusal_of(
    challenge: Challenge, run: Run, record: EpisodeRecord, now: dt.datetime
) -> Refusal | None:
    """:func:`video_refusal` of a run and an episode it has."""
    return video_refusal(challenge, run, run.id, record, record.position, 1, now)


def encoder_missing() -> str:
    """'' when this server can encode videos, else what to install."""
    try:
        check_encoder()
    except EncoderUnavailable as error:
        return f"Videos are off on this server: {error}"
    return ""


def episode_summary(record: EpisodeRecord) -> str:
    """A text account of an episode beside its video: how it ended, when FOUND was called,
    its scores (for those who cannot watch it)."""
    metrics, actions = record.metrics, record.actions
    founds = [str(step) for step, action in enumerate(actions, start=1) if action == "0"]
    called = f"FOUND called at step{'s' if len(founds) > 1 else ''} {', '.join(founds)}"
    parts = [
        f"Episode {record.position + 1}: {len(actions)} steps, ended by {record.end_reason}",
        f"{metrics.get('goals_found', 0)} goal(s) found" + (f"; {called}" if founds else ""),
        f"{metrics.get('collisions', 0)} collision(s), {float(metrics.get('path_length') or 0):.1f} m walked",
        ", ".join(
            f"{name} {100 * float(metrics.get(key) or 0):.1f}%"
            for key, name in (
                ("progress", "progress"),
                ("success", "success"),
                ("spl", "SPL"),
                ("ppl", "PPL"),
            )
        ),  # fmt: skip
    ]
    return ". ".join(parts) + "."
