"""Supervised pretraining of the image encoder before PPO (``--pretrain-vision``), and the same
data and head as a probe of a trained policy's visual features (``multion diagnose``).

The agents that must see their goal learned nothing in 720k frames of PPO (docs/learned.md): a
goal shows in few of the frames an untrained policy sees, so the RGB-D CNN gets almost no
signal to tell a cylinder from a wall. Here it first learns that from frames rendered at poses
in train houses, half of them facing a goal within ``max_distance`` (class-balanced), labelled
by ``goal_mask``: for each of the 8 categories, whether it shows and in which third of the
image (left, centre, right) the centre of its pixels lies. A linear head on the 512-d image
embedding ``v_i`` predicts the 8 labels; the head is dropped after, and PPO starts from the
encoder. A policy with a FOUND head (``--found-head``) learns its decision on the same frames:
the whole policy's first step of an episode that starts at the frame, labelled "FOUND would
succeed, and one can see it" where the frame shows the goal within the success distance.
Marza et al. (ICCV 2023) report that pre-trained perception lifts NoMap from 16.7 to 42.3 %
Success; their object locator is a pre-trained segmentation head.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn
from tqdm import tqdm

from multion.config.ranges import ConfigError
from multion.config.task import EnvConfig
from multion.task.spaces import build_observation_space
from multion_agents.learned.encoders import NUM_CATEGORY_VALUES, ImageEncoder
from multion_agents.learned.found_supervision import found_head_loss
from multion_agents.learned.learned_maps import ObjRecogMap, balancing_weights
from multion_agents.learned.policy import PolicyOutput, RecurrentPolicy
from multion_agents.learned.train_options import VisionPretraining
from multion_agents.learned.training_log import TrainingLog
from multion_agents.learned.vision_frames import VisionFrames, goal_in_view, sample_frames
from multion_client.constants import NUM_CATEGORIES

PLACES = 4
"""Per category: 0 not in view, 1 left, 2 centre, 3 right third of the image."""
DISTANCE_BANDS = ((0.0, 1.5), (1.5, 3.0), (3.0, 6.0), (6.0, math.inf))
"""Metres from the goal a frame is drawn around, for recall and precision by band (1.5 m:
FOUND's reach; 6 m: ``max_distance``'s default, and the goal heads' "seen")."""


class PlaceHead(nn.Module):
    """A linear head on the image embedding: the place logits (N, 8, 4) of every category."""

    def __init__(self, embedding: int) -> None:
        super().__init__()
        self.linear = nn.Linear(embedding, NUM_CATEGORIES * PLACES)

    def forward(self, v_i: Tensor) -> Tensor:
        logits: Tensor = self.linear(v_i).view(-1, NUM_CATEGORIES, PLACES)
        return logits


def class_weights(labels: np.ndarray) -> Tensor:
    """Inverse-frequency weights of the 4 places over all categories' labels, normalised to a
    mean of 1 over the labels (a place never seen gets the largest weight seen)."""
    counts = np.bincount(labels.reshape(-1), minlength=PLACES).astype(np.float64)
    weights = np.where(counts > 0, counts.sum() / np.maximum(counts, 1) / PLACES, 0.0)
    weights[counts == 0] = weights.max() if weights.max() > 0 else 1.0
    mean = float((weights[labels.reshape(-1)]).mean())
    return torch.as_tensor(weights / mean, dtype=torch.float32)


@dataclass(frozen=True)
class FoundPretraining:
    """What pretraining a FOUND head needs besides the frames: the ``policy`` whose first step
    decides, zero readings of its other sensors at an episode's start (``blank``, e.g. GPS and
    compass) and the task's ``success_distance``."""

    policy: RecurrentPolicy
    blank: dict[str, np.ndarray]
    success_distance: float

    @classmethod
    def of(cls, policy: RecurrentPolicy, env_config: EnvConfig) -> FoundPretraining | None:
        """None for a policy without a FOUND head."""
        if policy.found_head is None:
            return None
        space = build_observation_space(replace(env_config, sensors=policy.sensors))
        own = ("rgb", "depth", "goal")
        blank = {
            key: np.zeros(box.shape or (), dtype=box.dtype)
            for key, box in space.spaces.items()
            if key not in own
        }
        return cls(policy, blank, env_config.task.success_distance)

    def logits(self, frames: VisionFrames, index: np.ndarray) -> Tensor:
        """The FOUND head's logits (N,) at the first step of episodes starting at the frames."""
        device, count = self.policy.device, len(index)
        batch = {
            "rgb": torch.as_tensor(frames.rgb[index]),
            "depth": torch.as_tensor(frames.depth[index]),
            "goal": torch.as_tensor(frames.goal[index]),
            **{k: torch.as_tensor(np.stack([v] * count)) for k, v in self.blank.items()},
        }
        batch = {k: v[None].to(device) for k, v in batch.items() if k in self.policy.sensors}
        out: PolicyOutput = self.policy(
            batch,
            torch.zeros(1, count, dtype=torch.long, device=device),
            torch.ones(1, count, device=device),
            self.policy.initial_state(count),
        )
        assert out.found_logit is not None  # FoundPretraining.of: a policy with the head
        return out.found_logit[0]

    def labels(self, frames: VisionFrames, index: np.ndarray) -> Tensor:
        """1.0 where the frame shows its goal within the success distance (straight-line),
        else 0: the label PPO's rollouts give the head (``found_supervision.found_targets``)."""
        near = frames.distance[index] <= self.success_distance
        shows = goal_in_view(frames)[index]
        return torch.as_tensor(near & shows, dtype=torch.float32, device=self.policy.device)

    def held_out(self, frames: VisionFrames, chunk: int = 256) -> tuple[float, float]:
        """The head's mean probability on frames that show the goal within the success
        distance, and on the rest."""
        chances = []
        with torch.no_grad():
            for index in _chunks(len(frames), chunk):
                chances.append(torch.sigmoid(self.logits(frames, index)).cpu().numpy())
        chance = np.concatenate(chances)
        near = self.labels(frames, np.arange(len(frames))).cpu().numpy() > 0.5
        return _mean(chance[near]), _mean(chance[~near])


@dataclass(frozen=True)
class RecogniserPretraining:
    """ObjRecogMap's recogniser learning on the rendered frames too (``--pretrain-recogniser``),
    class-balanced: most frames show no goal within its 2.5 m."""

    memory: ObjRecogMap

    @classmethod
    def of(cls, policy: RecurrentPolicy) -> RecogniserPretraining:
        if not isinstance(policy.memory, ObjRecogMap):
            raise ConfigError(
                "--pretrain-recogniser trains ObjRecogMap's recogniser; this agent has none"
            )
        return cls(policy.memory)

    def loss(self, feature_map: Tensor, frames: VisionFrames, index: np.ndarray) -> Tensor:
        """Class-balanced cross-entropy of the recogniser on the frames' image features."""
        label = torch.as_tensor(frames.recognition[index], device=feature_map.device)
        weight = balancing_weights(label, NUM_CATEGORY_VALUES)
        return nn.functional.cross_entropy(
            self.memory.classifier(feature_map), label, weight=weight
        )

    def held_out(
        self, encoder: ImageEncoder, frames: VisionFrames, chunk: int = 256
    ) -> tuple[float, float]:
        """Recall (of the frames whose label names a goal, the share answered with that goal)
        and precision (of the frames answered with a goal, the share whose label it is)."""
        answer = recogniser_answers(self.memory, encoder, frames, chunk)
        label = frames.recognition
        hits = int(((answer == label) & (label > 0)).sum())
        named, answered = int((label > 0).sum()), int((answer > 0).sum())
        return (hits / named if named else math.nan, hits / answered if answered else math.nan)


def recogniser_answers(
    memory: ObjRecogMap, encoder: ImageEncoder, frames: VisionFrames, chunk: int = 256
) -> np.ndarray:
    """The recogniser's answer for each frame (N,): 0 "no goal", c + 1 category c."""
    device = next(memory.parameters()).device
    answers = []
    with torch.no_grad():
        for index in _chunks(len(frames), chunk):
            feature_map = _encode(encoder, frames, index, device)[0]
            answers.append(memory.classifier(feature_map).argmax(1).cpu().numpy())
    return np.concatenate(answers)


def _chunks(count: int, chunk: int) -> Iterator[np.ndarray]:
    """Indices 0 … count - 1 in consecutive arrays of at most ``chunk``."""
    for start in range(0, count, chunk):
        yield np.arange(start, min(start + chunk, count))


def _mean(values: np.ndarray) -> float:
    return float(values.mean()) if len(values) else math.nan


def _encode(
    encoder: ImageEncoder, frames: VisionFrames, index: np.ndarray, device: torch.device
) -> tuple[Tensor, Tensor]:
    """The encoder's feature map and embedding of the frames at ``index``."""
    rgb = torch.as_tensor(frames.rgb[index], device=device)
    depth = torch.as_tensor(frames.depth[index], device=device)
    feature_map, embedding = encoder(rgb, depth)
    return feature_map, embedding


@dataclass(frozen=True)
class BandScores:
    """Whether the goal a frame faces shows, predicted against the label, in one band."""

    band: tuple[float, float]
    frames: int
    in_view: int
    recall: float
    """Of the frames where the goal shows, the share predicted to show it (nan: none shows)."""
    precision: float
    """Of the frames predicted to show the goal, the share where it shows (nan: none)."""


def recall_precision(predicted: np.ndarray, actual: np.ndarray) -> tuple[float, float]:
    """Recall and precision of boolean predictions (nan where undefined)."""
    hits = int((predicted & actual).sum())
    shown, claimed = int(actual.sum()), int(predicted.sum())
    return (hits / shown if shown else math.nan, hits / claimed if claimed else math.nan)


def band_scores(
    predicted: np.ndarray, actual: np.ndarray, distance: np.ndarray
) -> list[BandScores]:
    """Recall and precision of "the goal shows" (booleans per frame) by distance band."""
    scores = []
    for low, high in DISTANCE_BANDS:
        inside = (distance >= low) & (distance < high)
        recall, precision = recall_precision(predicted & inside, actual & inside)
        scores.append(
            BandScores(
                (low, high), int(inside.sum()), int((actual & inside).sum()), recall, precision
            )
        )
    return scores


def predict_goal_in_view(
    encoder: ImageEncoder, head: PlaceHead, frames: VisionFrames, chunk: int = 256
) -> np.ndarray:
    """Per frame: whether the head says the frame's goal category shows."""
    device = next(head.parameters()).device
    out = []
    with torch.no_grad():
        for index in _chunks(len(frames), chunk):
            places = head(_encode(encoder, frames, index, device)[1]).argmax(-1).cpu().numpy()
            out.append(places[np.arange(len(index)), frames.goal[index]] > 0)
    return np.concatenate(out)


def fit_head(
    encoder: ImageEncoder,
    head: PlaceHead,
    frames: VisionFrames,
    settings: VisionPretraining,
    train_encoder: bool,
    log: TrainingLog | None = None,
    held_out: VisionFrames | None = None,
    progress: bool = False,
    found: FoundPretraining | None = None,
    recogniser: RecogniserPretraining | None = None,
) -> float:
    """Train ``head`` (and the encoder when ``train_encoder``; else a probe of frozen features)
    with class-weighted cross-entropy; returns the last loss. Every 100 steps a row goes to
    ``log`` ("pretrain_vision") with the held-out recall and precision over all bands.
    ``found``: the policy's FOUND head learns too (its binary cross-entropy added; the policy's
    weights trained), and the log gives its held-out mean probability near the goal and far.
    ``recogniser``: ObjRecogMap's recogniser learns too, and the log gives its held-out recall
    and precision."""
    device = next(head.parameters()).device
    weights = class_weights(frames.labels).to(device)
    trained: list[nn.Module] = [head]
    if train_encoder:
        trained.append(found.policy if found is not None else encoder)
        if recogniser is not None:
            trained.append(recogniser.memory.classifier)
    # the policy holds the encoder and the recogniser: each parameter once
    parameters = list({id(p): p for module in trained for p in module.parameters()}.values())
    optimizer = torch.optim.Adam(parameters, lr=settings.learning_rate, eps=1e-5)
    rng = np.random.default_rng(settings.seed)
    loss_value = math.nan
    for step in tqdm(
        range(1, settings.steps + 1), desc="vision", unit="step", disable=not progress
    ):
        index = rng.integers(len(frames), size=settings.batch_size)
        with torch.set_grad_enabled(train_encoder):
            feature_map, v_i = _encode(encoder, frames, index, device)
        logits = head(v_i if train_encoder else v_i.detach())
        labels = torch.as_tensor(frames.labels[index], device=device)
        loss = nn.functional.cross_entropy(
            logits.reshape(-1, PLACES), labels.reshape(-1), weight=weights
        )
        if found is not None:
            loss = loss + found_head_loss(found.logits(frames, index), found.labels(frames, index))
        if recogniser is not None:
            loss = loss + recogniser.loss(feature_map, frames, index)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        loss_value = loss.item()
        if log is not None and held_out is not None and (step % 100 == 0 or step == settings.steps):
            predicted = predict_goal_in_view(encoder, head, held_out)
            recall, precision = recall_precision(predicted, goal_in_view(held_out))
            row = {
                "step": step,
                "loss": loss_value,
                "held_out_recall": recall,
                "held_out_precision": precision,
            }
            if found is not None:
                row["found_near"], row["found_far"] = found.held_out(held_out)
            if recogniser is not None:
                row["recogniser_recall"], row["recogniser_precision"] = recogniser.held_out(
                    encoder, held_out
                )
            log.write("pretrain_vision", row)
    return loss_value


def check_vision_pretraining(
    settings: VisionPretraining, agent: str, sensors: tuple[str, ...], recogniser: bool = False
) -> None:
    """A ``ConfigError`` naming ``--pretrain-vision`` for an agent that does not see RGB-D, and
    ``--pretrain-recogniser`` (``recogniser``) without it."""
    if recogniser and settings.steps == 0:
        raise ConfigError("--pretrain-recogniser learns during --pretrain-vision STEPS: give it")
    if settings.steps > 0 and not {"rgb", "depth"} <= set(sensors):
        raise ConfigError(
            f"--pretrain-vision trains the RGB-D encoder, which {agent} does not have (it reads "
            f"{', '.join(sensors)})"
        )


def freeze_image_encoder(policy: RecurrentPolicy) -> None:
    """Take ``policy``'s image encoder out of training (``--freeze-vision``): its weights get no
    gradient, so the optimiser, which skips parameters without one, leaves them as they are."""
    if policy.image_encoder is None:
        raise ConfigError("--freeze-vision: this policy has no image encoder")
    policy.image_encoder.requires_grad_(False)


def pretrain_vision(
    policy: RecurrentPolicy,
    env_config: EnvConfig,
    settings: VisionPretraining,
    out: Path,
    progress: bool = True,
    recogniser: bool = False,
) -> list[BandScores]:
    """Train ``policy``'s image encoder on frames of train houses (log: ``out/pretrain_vision.csv``);
    returns the held-out (val houses) recall and precision by band after. ``recogniser``:
    ObjRecogMap's recogniser learns on the same frames (``--pretrain-recogniser``)."""
    encoder = policy.image_encoder
    if encoder is None:
        raise ConfigError("--pretrain-vision: this policy has no image encoder")
    train = sample_frames(env_config, settings.samples, settings.seed, settings, "train", progress)
    # val houses; other episodes of the file when training on a dataset file (tests, custom sets)
    held_split = "train" if env_config.dataset is not None else "val"
    held_out = sample_frames(
        env_config, settings.held_out, settings.seed + 1, settings, held_split, progress
    )
    head = PlaceHead(encoder.out_dim).to(policy.device)
    log = TrainingLog(out, tensorboard=False)
    try:
        found = FoundPretraining.of(policy, env_config)
        recognising = RecogniserPretraining.of(policy) if recogniser else None
        fit_head(encoder, head, train, settings, True, log, held_out, progress, found, recognising)
    finally:
        log.close()
    scores = band_scores(
        predict_goal_in_view(encoder, head, held_out), goal_in_view(held_out), held_out.distance
    )
    if progress:
        for row in scores:
            print(
                f"pretrain-vision, val frames {row.band[0]:g}-{row.band[1]:g} m: recall "
                f"{row.recall:.2f}, precision {row.precision:.2f} ({row.in_view}/{row.frames} "
                "show the goal)"
            )
    return scores
