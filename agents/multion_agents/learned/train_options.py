"""Training options read from the command line before anything heavy loads: the curriculum's
stages and how the map is pretrained. Here, not beside the code that runs them
(``rollout_envs``, ``pretrain``), so that ``train_settings`` (and ``multion train --help``)
import neither the simulator nor the env."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from multion.config.ranges import ConfigError, bounded, check_fields, one_of

EXPERTS = ("oracle-planner", "explorer")
"""Who labels the learner's states for ``--imitation-coef`` (``learned/expert.py``): the oracle
planner (it plans on an oracle map of the house) or the explorer (frontier exploration from
RGB-D and pose, what the learner's own sensors give)."""

FOUND_HEAD_LABELS = ("in-view", "seen")
"""Where ``--found-head`` learns that FOUND would succeed (``found_supervision.found_targets``):
within the success distance with the goal in the frame (``in-view``), or with the goal in view
at some step of the episode so far (``seen``, ``goal_vector``'s flag)."""

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


FOUND_BUDGET_UNLIMITED = 100_000
"""``task.found_budget`` during the FOUND curriculum: wrong FOUNDs never end an episode (the
config's maximum)."""


@dataclass(frozen=True)
class FoundCurriculum:
    """``--found-curriculum FRAMES:PENALTY``: until ``frames`` frames of the run, a wrong FOUND
    costs ``penalty`` but does not end the training episode; after, the task's own rule (the
    first wrong FOUND ends it, no penalty in the paper's task). ``frames`` = 0: off, the paper's
    recipe. Why: while an agent cannot find its goal, ending the episode by a wrong FOUND is
    its best policy (docs/learn-to-see.md), which is what the agents that must see learned."""

    frames: int = bounded(0, 0, 10**9)
    penalty: float = bounded(0.0, 0.0, 1000.0)
    """Subtracted from a wrong FOUND's reward during the curriculum (the reference code's
    ``FALSE_FOUND_PENALTY_VALUE`` is 2.5: saimwani/multiON ``ppo_multinav.yaml`` l. 23)."""

    def __post_init__(self) -> None:
        check_fields(self, "found_curriculum")

    @property
    def active(self) -> bool:
        return self.frames > 0


def parse_found_curriculum(text: str) -> FoundCurriculum:
    """``"200000:2.5"`` → ``FoundCurriculum(200000, 2.5)``; a ``ConfigError`` naming the option
    otherwise (a value out of range names the field and its range)."""
    frames, sep, penalty = text.partition(":")
    try:
        if not sep:
            raise ValueError
        parsed = (int(frames), float(penalty))
    except ValueError:
        raise ConfigError(
            f"--found-curriculum {text!r} is not FRAMES:PENALTY (e.g. 200000:2.5)"
        ) from None
    try:
        return FoundCurriculum(*parsed)
    except ValueError as error:
        raise ConfigError(f"--found-curriculum: {error}") from None


@dataclass(frozen=True)
class VisionPretraining:
    """How ``--pretrain-vision`` pretrains the image encoder (``steps`` = 0: not at all)."""

    steps: int = bounded(0, 0, 50_000)
    """Gradient steps."""
    samples: int = bounded(8_000, 200, 100_000)
    """Training frames, rendered once (half with the goal in view: class-balanced)."""
    held_out: int = bounded(1_000, 100, 10_000)
    """Frames of val houses to report recall and precision on."""
    batch_size: int = bounded(64, 1, 1_024)
    learning_rate: float = bounded(2.5e-4, 0.0, 1.0, low_open=True)
    max_distance: float = bounded(6.0, 1.0, 20.0)
    """Poses facing a goal keep it within this straight-line distance, metres."""
    poses_per_scene: int = bounded(40, 1, 1_000)
    seed: int = bounded(0, 0, 2**31 - 1)

    def __post_init__(self) -> None:
        check_fields(self, "pretrain_vision")
