"""``multion video``: film an episode of a ``multion eval`` run from its recorded actions.

Examples::

    multion video runs/op --episode val-3-on-00000
    multion video runs/op --episode val-3-on-00000 --out talk/op.mp4
    multion video runs/elsewhere --episode val-3-on-00007 --dataset my-val.json.gz
    multion video runs/op --episode val-3-on-00000 --still 100 --out slide.png

The episode is replayed in this process (same dataset, config and actions: the same frames
every time) and checked against its recorded metrics; the MP4 (H.264) shows the agent's RGB
and depth beside a top-down map, with a caption per step.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "run_dir", type=Path, metavar="RUN_DIR", help="a `multion eval --out` directory"
    )
    parser.add_argument("--episode", required=True, help="the episode id (see episodes.jsonl)")
    parser.add_argument(
        "--out", type=Path, default=None, help="the MP4 file (default RUN_DIR/episode-ID.mp4)"
    )
    parser.add_argument(
        "--still", type=int, default=None, metavar="STEP",
        help="write the frame of step STEP as a PNG instead of the video (0: the start)",
    )  # fmt: skip
    parser.add_argument(
        "--dataset", type=Path, default=None,
        help="the dataset file the run played, where its recorded path is not valid here",
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from multion.video.encoder import EncoderUnavailable, check_encoder
    from multion_agents.video.film import film_episode, still, video_name
    from multion_agents.video.recorded import VideoError, read_run

    try:
        if args.still is None:
            check_encoder()
        recorded_run = read_run(args.run_dir, args.dataset)
        recorded = recorded_run.episode(args.episode)
        name = video_name(recorded.episode_id)
        if args.still is not None:
            name = name.replace(".mp4", f"-step{args.still}.png")
        out = args.out or args.run_dir / name
        if not out.parent.is_dir():
            raise VideoError(f"--out {out}: the folder {out.parent} does not exist")
        if args.still is not None:
            if out.suffix.lower() != ".png":
                raise VideoError(f"--out {out}: a --still is a PNG file (name it .png)")
            still(recorded_run, recorded, args.still).save(out)
            print(f"wrote {out}")
            return 0
        film = film_episode(recorded_run, recorded, out)
    except (VideoError, EncoderUnavailable) as error:
        print(f"multion video: {error}", file=sys.stderr)
        return 2
    print(describe(film.path, film.frames, film.bytes, film.seconds))
    return 0


def describe(path: Path, frames: int, size: int, seconds: float) -> str:
    from multion.video.encoder import FPS

    return (
        f"wrote {path}: {frames} frames ({frames / FPS:.1f} s of video), "
        f"{size / 1e6:.2f} MB, made in {seconds:.1f} s"
    )
