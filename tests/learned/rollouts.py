"""Observation spaces and random rollouts shared by the learned-agent tests."""

from __future__ import annotations

import math
from pathlib import Path

import torch

from multion.config.codec import env_config_from_dict
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig
from multion.task.env import MultiONEnv
from multion.task.spaces import build_observation_space
from multion_agents.learned.models import MODELS
from multion_agents.learned.rollout import Rollout, compute_gae
from multion_agents.learned.train_settings import Args

SIZE = 64


def space_for(name: str):
    spec = MODELS[name]
    config = EnvConfig(sensors=spec.train_sensors, camera=CameraConfig(width=SIZE, height=SIZE))
    return build_observation_space(config)


def sample_frames(space, steps: int, batch: int, seed: int = 0) -> dict[str, torch.Tensor]:
    space.seed(seed)
    return {
        k: torch.stack(
            [
                torch.stack([torch.as_tensor(space[k].sample()) for _ in range(batch)])
                for _ in range(steps)
            ]
        )
        for k in space.spaces
    }


def random_rollout(space, seed: int, steps: int = 6, envs: int = 2) -> Rollout:
    """Random frames, actions, values and rewards, with advantages; ``initial_state`` empty."""
    generator = torch.Generator().manual_seed(seed)
    frames = sample_frames(space, steps, envs, seed)
    actions = torch.randint(0, 4, (steps, envs), generator=generator)
    rollout = Rollout(
        frames=frames,
        prev_actions=actions.roll(1, 0),
        starts=torch.zeros(steps, envs),
        actions=actions,
        logprobs=torch.full((steps, envs), math.log(0.25)),
        values=torch.randn(steps, envs, generator=generator),
        rewards=torch.randn(steps, envs, generator=generator),
        dones=torch.zeros(steps, envs),
        initial_state={},
    )
    rollout.starts[0] = 1.0
    compute_gae(rollout, torch.zeros(envs), 0.99, 0.95)
    return rollout


def actor_rollout(
    frames: dict[str, torch.Tensor],
    starts: torch.Tensor,
    initial_state: dict[str, torch.Tensor],
    generator: torch.Generator,
) -> Rollout:
    """A rollout of ``frames`` (T, E, ...) with episode ``starts`` (T, E): random previous and
    taken actions, values and rewards drawn from ``generator`` (in that order), with
    advantages."""
    steps, envs = starts.shape
    rollout = Rollout(
        frames=frames,
        prev_actions=torch.randint(0, 4, (steps, envs), generator=generator),
        starts=starts,
        actions=torch.randint(0, 4, (steps, envs), generator=generator),
        logprobs=torch.full((steps, envs), -1.3),
        values=torch.randn(steps, envs, generator=generator),
        rewards=torch.randn(steps, envs, generator=generator),
        dones=torch.roll(starts, -1, 0),
        initial_state=initial_state,
    )
    compute_gae(rollout, torch.zeros(envs), 0.99, 0.95)
    return rollout


def assert_same_loss_and_gradients(
    loss: float,
    gradients: dict[str, torch.Tensor],
    loss_before: float,
    gradients_before: dict[str, torch.Tensor],
) -> None:
    """The loss within 1e-5 and every gradient within 1e-4 of its largest entry."""
    assert abs(loss - loss_before) <= 1e-5 * max(1.0, abs(loss_before))
    assert gradients.keys() == gradients_before.keys()
    for name, expected in gradients_before.items():
        scale = float(expected.abs().max()) or 1.0
        error = float((gradients[name] - expected).abs().max()) / scale
        assert error < 1e-4, f"{name}: relative difference {error:.2e}"


def tiny_args(tmp_path: Path, dataset: Path, agent: str = "oracle-map", **changes) -> Args:
    """Settings of a run of a few updates on ``dataset`` (the room), changed by ``changes``."""
    values = dict(
        agent=agent,
        task="1-on",
        frames=192,
        envs=2,
        rollout_steps=32,
        image_size=SIZE,
        dataset=str(dataset),
        max_steps=40,
        out=str(tmp_path / "run"),
        progress=False,
        tensorboard=False,
    )
    values.update(changes)
    return Args(**values)


def room_env(dataset: Path, sensors: tuple[str, ...]) -> MultiONEnv:
    """A 1-ON env of ``dataset``'s train episodes (the room) with 16² images and ``sensors``."""
    config = {
        "task": {"num_goals": 1},
        "camera": {"width": 16, "height": 16},
        "sensors": list(sensors),
        "dataset": str(dataset),
        "split": "train",
    }
    return MultiONEnv(env_config_from_dict(config))
