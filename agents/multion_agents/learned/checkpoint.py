"""Training checkpoints: weights, optimiser state, progress, random states and the run's config.

A checkpoint is one ``torch.save`` file written atomically (temporary file, then rename), so an
interrupted save never leaves a half-written checkpoint behind.
"""

from __future__ import annotations

import random
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch

from multion.common.files import replacing
from multion.config.errors import UsageError
from multion_agents.agent import ConfigOverrides, merge_overrides
from multion_agents.learned.models import build_policy, model_spec
from multion_agents.learned.policy import RecurrentPolicy, hidden_size_of
from multion_agents.learned.train_settings import Args

FORMAT_VERSION = 1


class CheckpointError(UsageError, ValueError):
    """A file that is not a usable MultiON checkpoint."""


def save_checkpoint(path: Path, payload: dict[str, Any]) -> None:
    """Write ``payload`` (plus random states) to ``path`` atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        **payload,
        "format_version": FORMAT_VERSION,
        "rng": {
            "torch": torch.get_rng_state(),
            "torch_cuda": torch.cuda.get_rng_state_all() if torch.cuda.is_available() else [],
            "numpy": np.random.get_state(),
            "python": random.getstate(),
        },
    }
    with replacing(path) as temporary:
        torch.save(payload, temporary)


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    """Read a checkpoint, with a clear error for missing or foreign files."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint file")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as error:  # torch raises many kinds for corrupt files
        raise CheckpointError(f"{path}: not a readable checkpoint ({error})") from None
    if not isinstance(payload, dict) or payload.get("format_version") != FORMAT_VERSION:
        raise CheckpointError(f"{path}: not a MultiON checkpoint (format {FORMAT_VERSION})")
    for key in ("model", "agent", "env_config"):
        if key not in payload:
            raise CheckpointError(f"{path}: checkpoint has no {key!r} entry")
    return payload


def restore_random_states(payload: dict[str, Any]) -> None:
    rng = payload["rng"]
    torch.set_rng_state(rng["torch"])
    cuda_states = rng.get("torch_cuda", [])
    if cuda_states and len(cuda_states) == torch.cuda.device_count():
        torch.cuda.set_rng_state_all(cuda_states)
    np.random.set_state(rng["numpy"])
    random.setstate(rng["python"])


LEGACY_FIELDS: dict[str, dict[str, Any]] = {
    "maps": {"goal_cells": 1},
    "task": {"goal_set": "colours", "train_sampler": "online"},
}
"""Config fields added after checkpoints were first written, with the value those checkpoints
were trained with (issue 31 added ``maps.goal_cells``, goals were one cell before, and
``task.goal_set``, the cylinders were the only goals; issue 44 ``task.train_sampler``, train
episodes were drawn online). A recorded config lacking one gets this value, not today's
default."""


def with_legacy_fields(env_config: dict[str, Any]) -> dict[str, Any]:
    """``env_config`` (a checkpoint's) with the fields it predates set to their old values."""
    config = {k: (dict(v) if isinstance(v, dict) else v) for k, v in env_config.items()}
    for section, values in LEGACY_FIELDS.items():
        if isinstance(config.get(section), dict):
            config[section] = {**values, **config[section]}
    return config


TRAINING_ONLY_MODULES = ("goal_heads.", "critic_gru.")
"""Weights that only training reads (``--goal-heads``, ``--separate-critic``): left out of a
policy loaded to act."""


def acting_weights(weights: dict[str, Any]) -> dict[str, Any]:
    """``weights`` without the training-only heads."""
    return {k: v for k, v in weights.items() if not k.startswith(TRAINING_ONLY_MODULES)}


def load_policy(path: str | Path) -> tuple[RecurrentPolicy, ConfigOverrides, str]:
    """The trained policy in ``path``, the env overrides it needs (camera size, model
    overrides) and its model name. The checkpoint's own config is used (a checkpoint records
    every field), and its GRU size is read from its weights: checkpoints made with older
    defaults (13-cell crops, [0.5, 5] m depth, 512 GRU units) keep acting as trained."""
    payload = load_checkpoint(path)
    config = with_legacy_fields(payload["env_config"])
    try:
        hidden_size = hidden_size_of(payload["model"])
    except ValueError as error:
        raise CheckpointError(f"{path}: {error}") from None
    # without training heads; with the FOUND head and the pose input where it was trained with
    # them (they act)
    weights = payload["model"]
    found_head = "found_head.weight" in weights
    pose_input = "gps_embedding.weight" in weights
    # a FOUND head wider than the GRU also reads the frame's embedding
    reads_image = found_head and weights["found_head.weight"].shape[1] > hidden_size
    policy = build_policy(
        payload["agent"],
        config,
        hidden_size,
        found_head=found_head,
        pose_input=pose_input,
        found_head_reads_image=reads_image,
    )
    try:
        policy.load_state_dict(acting_weights(payload["model"]))
    except RuntimeError as error:
        raise CheckpointError(
            f"{path}: weights do not fit model {payload['agent']!r}: {error}"
        ) from None
    # the sections that shape observations; rewards and episode sources do not matter to eval,
    # nor does the renderer (the evaluating machine picks its own)
    shaping: dict[str, dict[str, Any]] = {
        section: dict(config[section]) for section in ("camera", "maps") if section in config
    }
    shaping.get("camera", {}).pop("renderer", None)
    goal_set = config.get("task", {}).get("goal_set", "colours")
    if goal_set != "colours":  # what the goals look like (the default set needs no override,
        shaping["task"] = {"goal_set": goal_set}  # so the agent can still join a track)
    overrides = merge_overrides(shaping, model_spec(payload["agent"]).config_overrides)
    return policy, overrides, payload["agent"]


RECIPE_OPTIONS = (
    "goal_heads",
    "found_supervision",
    "found_head",
    "found_head_positive_weight",
    "found_curriculum",
    "coverage_reward",
    "pretrain_vision",
    "pretrain_map",
    "balanced_recognition",
    "pretrain_recogniser",
    "expert",
    "pose_input",
    "separate_critic",
    "found_head_reads_image",
    "found_head_label",
    "freeze_vision",
)
"""Training options that make a different recipe: a run resumes only with the values its
checkpoint recorded (a checkpoint that predates an option was trained with it off)."""


def check_recipe_options(path: Path, recorded: dict[str, Any], args: Args) -> None:
    """A ``CheckpointError`` naming each recipe option whose value differs from the one the
    checkpoint at ``path`` recorded (``recorded``: its ``args``; an option, or a field of one,
    that it predates counts as its default)."""
    defaults, current = asdict(Args()), asdict(args)
    wrong = []
    for name in RECIPE_OPTIONS:
        default, value = defaults[name], recorded.get(name, defaults[name])
        if isinstance(default, dict) and isinstance(value, dict):
            value = {**default, **value}
        if value != current[name]:
            flag = "--" + name.replace("_", "-")
            wrong.append(f"{flag} {value!r} (this run asks for {current[name]!r})")
    if wrong:
        raise CheckpointError(
            f"{path} was trained with " + "; ".join(wrong) + ": resume with the same options"
        )
