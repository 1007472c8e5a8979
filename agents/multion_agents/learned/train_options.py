"""Training options read from the command line before anything heavy loads: the curriculum's
stages and how the map is pretrained. Here, not beside the code that runs them
(``rollout_envs``, ``pretrain``), so that ``train_settings`` (and ``multion train --help``)
import neither the simulator nor the env."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from multion.config.ranges import ConfigError, bounded, check_fields, one_of

Curriculum = tuple[tuple[int, float], ...]
"""``((until_frames, max_geodesic), ...)``: until ``until_frames`` frames of the run, online
training episodes keep each goal within ``max_geodesic`` metres (``online_max_geodesic``) of the
start or the previous goal; after the last stage, the task's own episodes."""


def parse_curriculum(texts: Sequence[str]) -> Curriculum:
    """``["240000:4", "480000:10"]`` → ``((240000, 4.0), (480000, 10.0))``; a ``ValueError``
    naming the stage otherwise."""
    stages = []
    for text in texts:
        frames, sep, metres = text.partition(":")
        try:
            if not sep:
                raise ValueError
            stages.append((int(frames), float(metres)))
        except ValueError:
            raise ConfigError(
                f"--curriculum stage {text!r} is not FRAMES:METRES (e.g. 240000:4)"
            ) from None
    return tuple(stages)


@dataclass(frozen=True)
class MapPretraining:
    """How ``--pretrain-map`` pretrains (``steps`` = 0: not at all)."""

    steps: int = bounded(0, 0, 20_000)
    """Gradient steps (the v3 recipe: 1,200)."""
    samples: int = bounded(12_000, 200, 100_000)
    """Training crops, drawn once (5 kB each with the default 50-cell crops, 1.3 kB with 25)."""
    held_out: int = bounded(1_000, 100, 10_000)
    """Crops to report the accuracy on, drawn from ``held_out_split``."""
    held_out_split: str = one_of("val", ("val", "train"))
    """``val``: val houses (other train episodes for tasks without a packaged val set);
    ``train``: other train episodes."""
    batch_size: int = bounded(128, 1, 4_096)
    learning_rate: float = bounded(2.5e-4, 0.0, 1.0, low_open=True)
    max_distance: float = bounded(9.0, 1.0, 50.0)
    """Poses keep the goal within this straight-line distance, metres."""
    found_fraction: float = bounded(0.8, 0.0, 1.0, low_open=True)
    """FOUND is the label within this fraction of the task's success distance (geodesic)."""
    poses_per_scene: int = bounded(60, 1, 1_000)
    """Poses per sampled episode before the next one (mostly in a new house)."""
    seed: int = bounded(0, 0, 2**31 - 1)

    def __post_init__(self) -> None:
        check_fields(self, "pretrain_map")
