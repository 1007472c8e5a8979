"""Offline pretraining of an oracle-map policy on map crops, before PPO (``--pretrain-map``).

On the v3 houses pure PPO does not learn from the oracle map within an hour of CPU frames
(docs/learned.md): crops along a trajectory are nearly the same picture many times over, so the
map's encoder gets too few distinct examples to learn where the goal is. Here the whole policy
is first trained by supervised learning on crops taken at random poses in many train houses:

- the goal (one of the episode's goals, its category the ``goal`` observation) is within
  ``max_distance`` metres in a straight line and reachable;
- the label is FOUND where the goal is within ``found_fraction`` × the success distance along
  the floor, else MOVE_FORWARD where its straight-line bearing is within half a turn of ahead,
  else the turn towards it.

The camera frames are blank (zeros) during pretraining, so only the map's pathway and the heads
learn; PPO then starts from a policy that already turns towards the goal on the map and calls
FOUND next to it.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from multion.config.datasets import packaged_dataset_path
from multion.config.episode import Episode, Goal
from multion.config.ranges import ConfigError
from multion.config.task import EnvConfig
from multion.sim.geodesic import distance_field
from multion.sim.navgrid import NavGrid
from multion.task.env import MultiONEnv
from multion.task.maps import OracleMap
from multion.task.spaces import build_observation_space
from multion_agents.learned.memory import Batch
from multion_agents.learned.policy import RecurrentPolicy
from multion_agents.learned.train_options import MapPretraining
from multion_agents.learned.training_log import TrainingLog
from multion_client.constants import Action

MAP_SENSOR = "oracle_map"
"""The observation pretraining draws: the whole-house oracle map's egocentric crop."""


@dataclass
class MapCrops:
    """Pretraining data: ``maps`` (N, S, S, 2) uint8 crops, ``goals`` (N,) the goal category,
    ``labels`` (N,) the action to take."""

    maps: np.ndarray
    goals: np.ndarray
    labels: np.ndarray

    def __len__(self) -> int:
        return len(self.labels)


def pose_label(
    position: np.ndarray,
    yaw: float,
    goal: np.ndarray,
    geodesic: float,
    found_within: float,
    turn_angle_deg: float,
) -> Action:
    """The action towards ``goal`` from a pose: FOUND within ``found_within`` metres of floor
    (``geodesic``), forward within half a turn of the goal's straight-line bearing, else the
    turn towards it (yaw counter-clockwise, so a positive bearing is to the left)."""
    if geodesic <= found_within:
        return Action.FOUND
    dx, dy = goal[0] - position[0], goal[1] - position[1]
    bearing = math.remainder(math.atan2(dy, dx) - yaw, 2 * math.pi)
    if abs(bearing) < math.radians(turn_angle_deg) / 2:
        return Action.MOVE_FORWARD
    return Action.TURN_LEFT if bearing > 0 else Action.TURN_RIGHT


def random_goals(
    env: MultiONEnv, rng: np.random.Generator, seed: int
) -> Iterator[tuple[NavGrid, Episode, Goal]]:
    """Endlessly: ``env`` reset into a random one of its episodes (a packaged split's or a
    file's), or into its next online episode, the first reset seeded by ``seed``; yields the
    house's grid, the episode and one of its goals drawn by ``rng`` (offline data: pretraining
    and probes draw poses around it)."""
    seeded: int | None = seed
    while True:
        options = {}
        if env.episodes is not None:  # else sampled online
            options = {"episode_index": int(rng.integers(len(env.episodes)))}
        env.reset(seed=seeded, options=options)
        seeded = None
        grid, episode = env.sim.grid, env.episode
        assert grid is not None and episode is not None
        yield grid, episode, episode.goals[int(rng.integers(len(episode.goals)))]


def sample_map_crops(
    env_config: EnvConfig,
    count: int,
    seed: int,
    settings: MapPretraining,
    split: str = "train",
    progress: bool = False,
) -> MapCrops:
    """``count`` labelled crops at random poses in episodes of ``env_config`` on ``split`` (a
    random episode, so mostly a new house, every ``poses_per_scene`` poses; ``seed`` picks the
    episodes and poses)."""
    # the split's packaged episodes, not a training file; the oracle map shows goals even
    # when they are not rendered
    dataset = env_config.dataset if split == "train" else None
    config = replace(
        env_config, sensors=("goal",), episodes_per_scene=1, split=split, dataset=dataset
    )
    found_within = settings.found_fraction * config.task.success_distance
    rng = np.random.default_rng(seed)
    maps: list[np.ndarray] = []
    goals: list[int] = []
    labels: list[int] = []
    env = MultiONEnv(config)
    bar = tqdm(total=count, desc="pretraining crops", unit="crop", disable=not progress)
    try:
        houses = random_goals(env, rng, seed)
        while len(labels) < count:
            grid, episode, goal = next(houses)
            oracle = OracleMap(grid, config.maps)
            oracle.set_goals((*episode.goals, *episode.distractors))
            target = np.asarray(goal.position[:2], dtype=np.float64)
            field = distance_field(grid, target, config.task.goal_radius)
            rows, cols = np.nonzero(np.isfinite(field))
            centres = grid.cell_to_world(rows, cols)
            near = np.hypot(*(centres - target).T) <= settings.max_distance
            rows, cols, centres = rows[near], cols[near], centres[near]
            if len(rows) == 0:
                continue
            for _ in range(min(settings.poses_per_scene, count - len(labels))):
                pick = rng.integers(len(rows))
                position = centres[pick]
                yaw = float(rng.uniform(-math.pi, math.pi))
                geodesic = float(field[rows[pick], cols[pick]])
                maps.append(oracle.egocentric(oracle.layers, position, yaw))
                goals.append(goal.category)
                labels.append(
                    pose_label(
                        position,
                        yaw,
                        target,
                        geodesic,
                        found_within,
                        config.agent.turn_angle_deg,
                    )
                )
                bar.update(1)
    finally:
        bar.close()
        env.close()
    return MapCrops(np.stack(maps), np.asarray(goals, np.int64), np.asarray(labels, np.int64))


def _logits(
    policy: RecurrentPolicy, blank: Batch, crops: MapCrops, index: np.ndarray
) -> torch.Tensor:
    """The policy's action logits at the first step of ``len(index)`` episodes whose frames are
    the crops, their goals and ``blank``'s other observations (one frame each, repeated)."""
    batch = len(index)
    device = policy.device
    frames = {key: value.expand(1, batch, *value.shape[2:]) for key, value in blank.items()}
    frames[MAP_SENSOR] = torch.as_tensor(crops.maps[index][None], device=device)
    frames["goal"] = torch.as_tensor(crops.goals[index][None], device=device)
    output = policy(
        frames,
        torch.zeros(1, batch, dtype=torch.long, device=device),
        torch.ones(1, batch, device=device),
        policy.initial_state(batch),
    )
    logits: torch.Tensor = output.logits[0]
    return logits


def blank_frames(policy: RecurrentPolicy, env_config: EnvConfig) -> Batch:
    """One all-zero frame (1, 1, ...) of each observation ``policy`` reads in ``env_config``."""
    space = build_observation_space(env_config)
    if MAP_SENSOR not in policy.sensors:
        raise ConfigError(
            f"--pretrain-map trains on the {MAP_SENSOR!r} observation; this agent reads "
            f"{', '.join(policy.sensors)}"
        )
    frames: Batch = {}
    for key in policy.sensors:
        shape = space[key].shape
        assert shape is not None  # only a Dict space has no shape
        frames[key] = torch.as_tensor(np.zeros((1, 1, *shape), space[key].dtype)).to(policy.device)
    return frames


def accuracy(policy: RecurrentPolicy, blank: Batch, crops: MapCrops, chunk: int = 500) -> float:
    """The share of ``crops`` whose most likely action is the label."""
    hits = 0
    with torch.no_grad():
        for start in range(0, len(crops), chunk):
            index = np.arange(start, min(start + chunk, len(crops)))
            predicted = _logits(policy, blank, crops, index).argmax(-1).cpu().numpy()
            hits += int((predicted == crops.labels[index]).sum())
    return hits / len(crops)


def check_map_pretraining(settings: MapPretraining, agent: str, sensors: tuple[str, ...]) -> None:
    """A ValueError naming ``--pretrain-map`` when ``settings`` asks to pretrain ``agent``
    (reading ``sensors``), which has no oracle map."""
    if settings.steps > 0 and MAP_SENSOR not in sensors:
        raise ConfigError(
            f"--pretrain-map trains on the {MAP_SENSOR!r} observation, which {agent} does not "
            f"read (it reads {', '.join(sensors)})"
        )


def pretrain_map(
    policy: RecurrentPolicy,
    env_config: EnvConfig,
    settings: MapPretraining,
    out: Path,
    progress: bool = True,
) -> dict[str, float]:
    """Train ``policy`` (whose observations include ``oracle_map``) on crops of train houses,
    logging every 100 steps to ``out/pretrain.csv``; returns the last step's loss and the
    held-out accuracy (on crops of val houses) before and after."""
    log = TrainingLog(out, tensorboard=False)
    try:
        result = _fit(policy, env_config, settings, log, progress)
    finally:
        log.close()
    if progress:
        print(
            f"pretrained on {settings.samples} map crops for {settings.steps} steps: held-out "
            f"accuracy {100 * result['held_out_accuracy_before']:.0f} % → "
            f"{100 * result['held_out_accuracy']:.0f} %"
        )
    return result


def _fit(
    policy: RecurrentPolicy,
    env_config: EnvConfig,
    settings: MapPretraining,
    log: TrainingLog,
    progress: bool,
) -> dict[str, float]:
    blank = blank_frames(policy, env_config)
    train_crops = sample_map_crops(
        env_config, settings.samples, settings.seed, settings, "train", progress
    )
    task = env_config.task
    has_val = packaged_dataset_path(task.num_goals, "val", task.num_distractors).is_file()
    use_val = settings.held_out_split == "val" and has_val
    held_out = sample_map_crops(
        env_config,
        settings.held_out,
        settings.seed + 1,
        settings,
        "val" if use_val else "train",
        progress,
    )
    rng = np.random.default_rng(settings.seed)
    optimizer = torch.optim.Adam(policy.parameters(), lr=settings.learning_rate, eps=1e-5)
    before = accuracy(policy, blank, held_out)
    row: dict[str, float] = {"step": 0, "loss": math.nan, "held_out_accuracy": before}
    log.write("pretrain", row)
    for step in tqdm(
        range(1, settings.steps + 1), desc="pretraining", unit="step", disable=not progress
    ):
        index = rng.integers(len(train_crops), size=settings.batch_size)
        labels = torch.as_tensor(train_crops.labels[index], device=policy.device)
        loss = torch.nn.functional.cross_entropy(_logits(policy, blank, train_crops, index), labels)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        if step % 100 == 0 or step == settings.steps:
            row = {
                "step": step,
                "loss": loss.item(),
                "held_out_accuracy": accuracy(policy, blank, held_out),
            }
            log.write("pretrain", row)
    return {**row, "held_out_accuracy_before": before}
