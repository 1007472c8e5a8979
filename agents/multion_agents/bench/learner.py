"""``multion bench --only learner``: the learner's cost per frame for each agent, no simulator.

The rollout is synthetic (observations drawn from the environment's observation space with a
fixed seed) but shaped as the central comparison's recipe (``scripts/central_comparison.sh``):
environments in two groups (8, 16, 32 and 64 by default: one row each), 128 steps per update,
36² RGB-D (``--learner-image-size``), the reference's defaults (50-cell oracle crop, 768-unit
GRU, 4 mini-batches, so a mini-batch holds a quarter of the environments and grows with them);
``--learner-freeze-vision`` adds a row per agent with its image encoder frozen. The two timed
parts are the trainer's own code:

1. **acting**: ``policy.get_action_and_value`` for each group of environments, step by step,
   with the frames copied to the device as the trainer copies them;
2. **updating**: ``compute_gae`` and ``ppo_update`` (the recipe's epochs and mini-batches).

The learner's frames/s (1000 / learner ms per frame) is the most a training run could make if
simulation were free, so comparing it with ``--only train``'s bare simulation rate says which of
the two bounds an agent on a machine. It needs neither PyBullet nor a scene, so it also runs on a
GPU machine that has only torch (``--device cuda``, with ``--learner-mixed-precision bf16``
to time the update under autocast).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from gymnasium import spaces
from torch import Tensor

from multion.config.codec import env_config_from_dict
from multion.task.spaces import build_observation_space
from multion_agents.bench.train import cuda_missing
from multion_agents.learned.distributed import cores_per_rank, select_device
from multion_agents.learned.memory import State
from multion_agents.learned.models import MODELS, build_policy, model_spec
from multion_agents.learned.policy import frames_to_tensors
from multion_agents.learned.ppo import ppo_update
from multion_agents.learned.precision import PRECISIONS
from multion_agents.learned.rollout import Rollout, compute_gae, store_frame
from multion_agents.learned.rollout_envs import training_env_config
from multion_agents.learned.train_settings import Args
from multion_agents.learned.vision_pretrain import freeze_image_encoder

AGENTS = ("no-map", "oracle-map", "oracle-ego-map", "proj-neural-map", "obj-recog-map")
"""The central comparison's learned agents (Table 3 at 1-ON)."""
MIN_IMAGE_SIZE, MAX_IMAGE_SIZE = 36, 128
"""The image encoder's smallest input, and the 128² recipe's: a synthetic rollout of 128² RGB-D
holds 0.9 GB of frames at 64 environments, 3.8 GB at the 256 that ``--learner-envs`` allows."""


@dataclass(frozen=True)
class LearnerBench:
    agents: tuple[str, ...] = AGENTS
    device: str = "cpu"
    env_counts: tuple[int, ...] = (8, 16, 32, 64)
    """One row per number of environments."""
    image_size: int = 36
    rollout_steps: int = 128
    updates: int = 2
    """Timed updates; one more before them is a warm-up."""
    mixed_precision: str = "off"
    freeze_vision: bool = False
    """Also time each agent with its image encoder frozen (``--freeze-vision``: no gradient,
    outputs kept from acting), a row each."""
    episode_steps: int = 50
    """Mean episode length of the synthetic rollout (a new episode starts with probability
    1 / ``episode_steps``): an untrained policy's episodes end every few dozen steps."""


def parse_counts(option: str, text: str, high: int) -> tuple[int, ...]:
    """Comma-separated environment counts, or a ``ValueError`` naming ``option`` and the range."""
    try:
        counts = tuple(int(part) for part in text.split(","))
    except ValueError:
        raise ValueError(f"{option} {text!r}: comma-separated whole numbers") from None
    if any(not 1 <= count <= high for count in counts):
        raise ValueError(f"{option} {text!r}: each count in 1-{high}")
    return counts


def learner_settings(
    agents: str | None, updates: int, device: str, envs: str | None = None,
    mixed_precision: str = "off", image_size: int = 36, freeze_vision: bool = False,
) -> LearnerBench:  # fmt: skip
    """The bench of ``--learner-agents`` (comma-separated; None: :data:`AGENTS`) and
    ``--learner-envs`` (comma-separated; None: 8,16,32,64), or a ``ValueError`` naming the
    option and what it allows."""
    env_counts = (
        LearnerBench.env_counts if envs is None else parse_counts("--learner-envs", envs, 256)
    )
    names = tuple(agents.split(",")) if agents else AGENTS
    unknown = [name for name in names if name not in MODELS]
    if unknown:
        raise ValueError(
            f"--learner-agents: unknown agent(s) {', '.join(unknown)}; known: {', '.join(MODELS)}"
        )
    if updates < 1:
        raise ValueError(f"--learner-updates {updates}: at least 1 timed update")
    if not MIN_IMAGE_SIZE <= image_size <= MAX_IMAGE_SIZE:
        raise ValueError(
            f"--learner-image-size {image_size}: in {MIN_IMAGE_SIZE}-{MAX_IMAGE_SIZE} pixels"
        )
    if mixed_precision not in PRECISIONS:
        raise ValueError(
            f"--learner-mixed-precision {mixed_precision!r}: one of {', '.join(PRECISIONS)}"
        )
    return LearnerBench(
        agents=names, device=device, updates=updates, env_counts=env_counts,
        mixed_precision=mixed_precision, image_size=image_size, freeze_vision=freeze_vision,
    )  # fmt: skip


def synthetic_frames(
    observation_space: spaces.Dict, keys: Sequence[str], steps: int, envs: int, seed: int
) -> dict[str, Tensor]:
    """(T, E, ...) observations drawn uniformly within the spaces (unbounded ones within ±5)."""
    rng = np.random.default_rng(seed)
    frames: dict[str, Tensor] = {}
    for key in keys:
        space = observation_space[key]
        if isinstance(space, spaces.Discrete):  # the goal's category
            frames[key] = torch.from_numpy(rng.integers(0, int(space.n), (steps, envs)))
            continue
        if not isinstance(space, spaces.Box):
            raise TypeError(f"sensor {key!r}: no synthetic frames for {space}")
        size = (steps, envs, *space.shape)
        if space.dtype == np.uint8:
            top = int(np.max(space.high))
            frames[key] = torch.from_numpy(rng.integers(0, top + 1, size, dtype=np.uint8))
        else:
            low, high = np.maximum(space.low, -5.0), np.minimum(space.high, 5.0)
            frames[key] = torch.from_numpy(rng.uniform(low, high, size).astype(space.dtype))
    return frames


def _synchronize(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def time_agent(
    agent: str, bench: LearnerBench, envs: int, frozen: bool = False
) -> dict[str, float]:
    """Acting and updating ms per frame of ``agent`` with ``envs`` environments (means over the
    timed updates); ``frozen``: with the image encoder frozen as ``--freeze-vision`` freezes it."""
    device = select_device(bench.device)
    spec = model_spec(agent)
    config = training_env_config(1, spec.train_sensors, bench.image_size, "train",
                                 spec.config_overrides)  # fmt: skip
    env_config = env_config_from_dict(config)
    args = Args(agent=agent, envs=envs, image_size=bench.image_size,
                rollout_steps=bench.rollout_steps, progress=False, tensorboard=False,
                mixed_precision=bench.mixed_precision)  # fmt: skip
    torch.manual_seed(0)
    policy = build_policy(agent, config, args.hidden_size).to(device)
    if frozen:
        freeze_image_encoder(policy)
    optimizer = torch.optim.Adam(policy.parameters(), lr=args.learning_rate, eps=1e-5)
    keys, steps = policy.train_sensors, bench.rollout_steps
    frames = synthetic_frames(build_observation_space(env_config), keys, steps, envs, seed=0)
    groups = [slice(0, envs // 2), slice(envs // 2, envs)] if envs > 1 else [slice(0, 1)]
    generator = torch.Generator().manual_seed(0)
    act_threads, update_threads = max(1, args.threads), args.update_threads or cores_per_rank()
    acted, updated = [], []
    for update in range(bench.updates + 1):
        starts = (torch.rand(steps, envs, generator=generator) < 1 / bench.episode_steps).float()
        starts[0] = 1.0
        columns = {k: torch.zeros(steps, envs) for k in ("logprob", "value")}
        actions = torch.zeros(steps, envs, dtype=torch.long)
        prev = torch.zeros(steps, envs, dtype=torch.long)
        rollout_frames = dict(frames)  # a frozen encoder's outputs join them while acting
        state: State = policy.initial_state(envs)
        initial_state = {k: v.detach().cpu().clone() for k, v in state.items()}
        torch.set_num_threads(act_threads)
        _synchronize(device)
        tick = time.perf_counter()
        for t in range(steps):
            for rows in groups:
                observed = frames_to_tensors({k: frames[k][t, rows].numpy() for k in keys}, keys)
                frame = policy.cache_images({k: v.to(device) for k, v in observed.items()})
                store_frame(rollout_frames, t, rows, {**frame, **observed})
                with torch.no_grad():
                    action, logprob, value, new_state = policy.get_action_and_value(
                        frame,
                        prev[t, rows].to(device),
                        starts[t, rows].to(device),
                        {k: v[rows] for k, v in state.items()},
                    )
                for k, v in new_state.items():
                    state[k][rows] = v
                actions[t, rows] = action.cpu()
                columns["logprob"][t, rows] = logprob.cpu()
                columns["value"][t, rows] = value.cpu()
                if t + 1 < steps:
                    prev[t + 1, rows] = actions[t, rows]
        _synchronize(device)
        act_seconds = time.perf_counter() - tick
        rollout = Rollout(
            frames=rollout_frames, prev_actions=prev, starts=starts, actions=actions,
            logprobs=columns["logprob"], values=columns["value"],
            rewards=torch.randn(steps, envs, generator=generator) * 0.1,
            dones=torch.roll(starts, -1, 0), initial_state=initial_state,
        )  # fmt: skip
        torch.set_num_threads(update_threads)
        tick = time.perf_counter()
        compute_gae(rollout, torch.zeros(envs), args.gamma, args.gae_lambda)
        ppo_update(policy, optimizer, rollout, args, args.clip)
        _synchronize(device)
        update_seconds = time.perf_counter() - tick
        torch.set_num_threads(act_threads)
        if update > 0:  # the first update is a warm-up
            acted.append(act_seconds)
            updated.append(update_seconds)
    per_frame = steps * envs
    act_ms = 1000 * float(np.mean(acted)) / per_frame
    update_ms = 1000 * float(np.mean(updated)) / per_frame
    return {"act_ms": act_ms, "update_ms": update_ms, "fps": 1000 / (act_ms + update_ms)}


def _sees(agent: str) -> bool:
    spec = model_spec(agent)
    return spec.use_rgb or spec.use_depth


def run_learner_bench(bench: LearnerBench) -> dict[str, dict[int, dict[str, float]]] | None:
    """Print and return each agent's learner figures for each number of environments; None
    (with the reason printed) when the device asked for is not there."""
    if cuda_missing(bench.device, "learner"):
        return None
    name = torch.cuda.get_device_name() if bench.device.startswith("cuda") else "cpu"
    print(
        f"learner bench: 1-ON, {bench.image_size}² RGB-D, envs in 2 groups, "
        f"{bench.updates} timed updates of {bench.rollout_steps} steps (after a warm-up), "
        f"reference defaults, mixed precision {bench.mixed_precision}; device {bench.device} "
        f"({name}), {cores_per_rank()} cores, synthetic observations (no simulator)"
    )
    columns = ("envs", "acting", "updating", "learner", "learner", "vs no-map")
    print(f"{'agent':>22} " + " ".join(f"{c:>10}" for c in columns))
    units = ("", "ms/frame", "ms/frame", "ms/frame", "frames/s", "(time)")
    print(f"{'':>22} " + " ".join(f"{c:>10}" for c in units))
    results: dict[str, dict[int, dict[str, float]]] = {}
    variants = [(agent, False) for agent in bench.agents]
    if bench.freeze_vision:  # agents without an image encoder have nothing to freeze
        variants += [(a, True) for a in bench.agents if _sees(a)]
    for agent, frozen in variants:
        name = f"{agent} frozen" if frozen else agent
        results[name] = {}
        for envs in bench.env_counts:
            result = time_agent(agent, bench, envs, frozen)
            results[name][envs] = result
            total = result["act_ms"] + result["update_ms"]
            base = results.get("no-map", {}).get(envs)
            ratio = (
                f"{total / (base['act_ms'] + base['update_ms']):9.1f}×" if base else f"{'-':>10}"
            )
            print(
                f"{name:>22} {envs:10d} {result['act_ms']:10.2f} {result['update_ms']:10.2f} "
                f"{total:10.2f} {result['fps']:10.0f} {ratio}"
            )
    for agent, frozen in variants:
        if frozen:
            speedups = ", ".join(
                f"{envs} envs {results[agent][envs]['update_ms'] / row['update_ms']:.2f}×"
                for envs, row in results[f"{agent} frozen"].items()
            )
            print(f"{agent}: update with the encoder frozen, faster by {speedups}")
    return results
