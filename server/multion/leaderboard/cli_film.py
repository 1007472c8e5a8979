"""``multion leaderboard replay RUN_ID --video DIR [--episode N ...]``: the organiser films
the episodes of any stored run (sealed phases included), from its stored actions."""

from __future__ import annotations

from pathlib import Path

from multion.leaderboard.challenge import Challenge
from multion.leaderboard.models import Run
from multion.leaderboard.run_videos import film_run
from multion.leaderboard.storage import Database, StorageError, check_secret
from multion.video.encoder import EncoderUnavailable, check_encoder
from multion.video.stored import Film, VideoError


def film(
    db: Database, challenge: Challenge, run_id: str, numbers: list[int] | None, out_dir: Path
) -> list[Film]:
    """Film and report each film; a StorageError names what went wrong (the CLI prints it)."""
    try:
        check_encoder()
        with db.sessions() as session:
            check_secret(session, challenge.secret, remember=False)
            run = session.get(Run, run_id)
            if run is None:
                raise StorageError(f"no run {run_id!r}")
            return film_run(challenge, run, numbers, out_dir, _report)
    except (EncoderUnavailable, VideoError) as error:
        raise StorageError(str(error)) from None


def _report(made: Film) -> None:
    print(
        f"wrote {made.path} ({made.frames} frames, {made.bytes / 1e6:.2f} MB, "
        f"{made.seconds:.1f} s) and its captions {made.captions}"
    )
