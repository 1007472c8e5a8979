"""Training checkpoints: weights, optimiser state, progress, random states and the run's config.

A checkpoint is one ``torch.save`` file written atomically (temporary file, then rename), so an
interrupted save never leaves a half-written checkpoint behind.
"""

from __future__ import annotations

import os
import random
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

from multion_agents.agent import ConfigOverrides, merge_overrides
from multion_agents.learned.map_ops import MapGeometry
from multion_agents.learned.models import model_spec
from multion_agents.learned.policy import RecurrentPolicy

FORMAT_VERSION = 1


class CheckpointError(ValueError):
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
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(handle)
    try:
        torch.save(payload, temporary)
        os.chmod(temporary, 0o644)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


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


def build_policy(agent: str, env_config: dict[str, Any]) -> RecurrentPolicy:
    """The (untrained) policy of model ``agent`` for environments configured by ``env_config``."""
    from multion.api.config_io import env_config_from_dict
    from multion.task.env import build_observation_space

    config = env_config_from_dict(env_config)
    space = build_observation_space(config)
    return model_spec(agent).build(space, MapGeometry.from_env_config(config))


def load_policy(path: str | Path) -> tuple[RecurrentPolicy, ConfigOverrides, str]:
    """The trained policy in ``path``, the env overrides it needs (camera size, model
    overrides) and its model name."""
    payload = load_checkpoint(path)
    policy = build_policy(payload["agent"], payload["env_config"])
    try:
        policy.load_state_dict(payload["model"])
    except RuntimeError as error:
        raise CheckpointError(
            f"{path}: weights do not fit model {payload['agent']!r}: {error}"
        ) from None
    config = payload["env_config"]
    # the sections that shape observations; rewards and episode sources do not matter to eval,
    # nor does the renderer (the evaluating machine picks its own)
    shaping = {section: dict(config[section]) for section in ("camera", "maps") if section in config}
    shaping.get("camera", {}).pop("renderer", None)
    overrides = merge_overrides(shaping, model_spec(payload["agent"]).config_overrides)
    return policy, overrides, payload["agent"]
