"""Videos of a stored run's episodes: who may see them, and filming one from its actions.

The run pages show them only where the phase's feedback gives per-episode detail (minival),
once the run has ended, never on an aggregate or a sealed phase (:func:`video_refusal`); the
organiser's ``multion leaderboard replay RUN_ID --video DIR`` films any run. A film is the
episode regenerated from the secret, its stored actions played again with an RGB-D camera and
checked against the stored metrics (:mod:`multion.video`).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from multion.config.episode import Episode
from multion.leaderboard import drawing_entry
from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.leaderboard.models import EpisodeRecord, Run
from multion.video.stored import FILMED_SENSORS, Film, StoredEpisode, VideoError, check_length

REPLAYED_ENDS = ("success", "wrong_found", "max_steps")
"""End reasons a replay reproduces; a timeout or an abandon ends where the actions end, and
keeps the run's own end reason (as :func:`multion.leaderboard.replay.replay_run` does)."""


@dataclass(frozen=True)
class Refusal:
    """Why a video is not shown: an HTTP status and a message naming the reason."""

    status: int
    message: str


def video_refusal(
    challenge: Challenge, run: Run | None, run_id: str, record: EpisodeRecord | None,
    position: int, episodes: int, now: dt.datetime,
) -> Refusal | None:  # fmt: skip
    """None when a participant may watch episode ``position`` of ``run`` now; else why not.
    ``episodes`` is how many episodes the run stored (to name the valid positions)."""
    if run is None:
        return Refusal(404, f"no run {run_id!r}")
    track = challenge.track(run.track)
    phase = track.phase(run.phase) if track is not None else None
    if track is None or phase is None:
        return Refusal(404, f"run {run_id}: the challenge has no phase {run.track}/{run.phase}")
    where = f"phase {run.track}/{run.phase}"
    if not phase.results_visible(now):
        until = phase.sealed_until.isoformat() if phase.sealed_until else "?"
        return Refusal(403, f"{where} is sealed until {until}: no per-episode videos")
    if phase.feedback != "episodes":
        return Refusal(403, f"{where} shows aggregate results only: no per-episode videos")
    if run.refunded:
        return Refusal(403, f"run {run_id} was refunded (the server broke it): it shows nothing")
    if run.summary is None:
        return Refusal(409, f"run {run_id} has not ended: its videos come once it ends")
    if record is None:
        valid = f"positions 0 to {episodes - 1}" if episodes else "no episodes"
        return Refusal(404, f"run {run_id} has no episode {position} (it has {valid})")
    if not record.actions:
        return Refusal(404, f"episode {position} of run {run_id} was not played: nothing to film")
    try:
        check_length([int(a) for a in record.actions], f"{position} of run {run_id}")
    except VideoError as error:
        return Refusal(422, str(error))
    return None


@dataclass(frozen=True)
class EpisodeFilm:
    """One episode of a run to film (picklable: it runs in the picture drawer's process)."""

    track: Track
    phase: Phase
    maps: dict[str, Any]
    stored: StoredEpisode
    out: Path
    captions: Path

    def film(self) -> Film:
        """Film the episode in this process (the drawer's helper: it loads the simulator)."""
        config_dict = self.track.env_config(self.phase, FILMED_SENSORS, self.maps)
        return drawing_entry.film(config_dict, self.stored, self.out, self.captions)


def episode_film(
    track: Track, phase: Phase, run: Run, record: EpisodeRecord, episode: Episode,
    out: Path, captions: Path,
) -> EpisodeFilm:  # fmt: skip
    """The film of ``record`` (stored episode ``episode``), written to ``out`` and ``captions``.
    Its title names the method, the track and phase and the episode's number on the run page:
    never the hidden episode or house ids."""
    metrics = dict(record.metrics)
    if record.end_reason not in REPLAYED_ENDS:
        metrics.pop("end_reason", None)
    number = record.position + 1
    stored = StoredEpisode(
        episode,
        tuple(int(action) for action in record.actions),
        metrics,
        f"{number} of run {run.id}",
        f"{run.method} · {track.name} {phase.name} · episode {number}",
    )
    return EpisodeFilm(track, phase, dict(run.maps or {}), stored, out, captions)


ORGANISER_DEFAULT_FILMS = 3
"""``replay --video DIR`` without ``--episode``: the run's first played episodes."""


def film_run(
    challenge: Challenge, run: Run, numbers: list[int] | None, out_dir: Path,
    progress: Callable[[Film], None] | None = None,
) -> list[Film]:  # fmt: skip
    """The organiser's films of ``run`` (any phase, sealed ones included) in ``out_dir``:
    episodes ``numbers`` as the run page numbers them (1 = the first), by default its first
    played ones; ``<run id>-episode-<n>.mp4`` with its ``.vtt`` captions."""
    from multion.leaderboard.hidden import HiddenEpisodes
    from multion.leaderboard.live_run import draw_of
    from multion.leaderboard.storage import StorageError

    track = challenge.track(run.track)
    phase = track.phase(run.phase) if track is not None else None
    if track is None or phase is None:
        raise StorageError(f"run {run.id}: the challenge has no phase {run.track}/{run.phase}")
    if run.state == "running":
        raise StorageError(f"run {run.id} is still running; film it once it is over")
    if out_dir.exists() and not out_dir.is_dir():
        raise StorageError(f"--video {out_dir}: a file, not a folder")
    records = {r.position + 1: r for r in run.episodes}
    if numbers is None:
        chosen = [r for _, r in sorted(records.items()) if r.actions][:ORGANISER_DEFAULT_FILMS]
    else:
        unknown = [n for n in numbers if n not in records]
        if unknown:
            raise StorageError(
                f"--episode {unknown[0]}: run {run.id} has episodes 1 to {len(records)}"
            )
        chosen = [records[n] for n in numbers]
    for record in chosen:
        if not record.actions:
            raise StorageError(
                f"--episode {record.position + 1}: that episode of run {run.id} was not played"
            )
        check_length([int(a) for a in record.actions], f"{record.position + 1} of run {run.id}")
    out_dir.mkdir(parents=True, exist_ok=True)
    hidden, draw, films = HiddenEpisodes(challenge, in_subprocess=False), draw_of(run), []
    for record in chosen:
        episode = hidden.episode(track, phase, draw, record.position)
        stem = out_dir / f"{run.id}-episode-{record.position + 1}"
        job = episode_film(
            track, phase, run, record, episode, stem.with_suffix(".mp4"), stem.with_suffix(".vtt")
        )
        films.append(job.film())
        if progress is not None:
            progress(films[-1])
    return films
