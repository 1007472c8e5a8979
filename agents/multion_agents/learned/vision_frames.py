"""Labelled frames for vision pretraining and its probe (``vision_pretrain.py``): the camera's
RGB-D at poses drawn around goals in houses of a split, each with the place of every category
in the image, the goal it was drawn around, its distance and ObjRecogMap's recognition label."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import torch
from tqdm import tqdm

from multion.config.task import EnvConfig
from multion.task.env import MultiONEnv
from multion.task.maps import can_see
from multion_agents.learned.learned_maps import recognition_label
from multion_agents.learned.map_ops import MapGeometry
from multion_agents.learned.pretrain import random_goals
from multion_agents.learned.train_options import VisionPretraining
from multion_client.constants import NUM_CATEGORIES

SIGHT_TRIES = 30
"""Cells tried for a pose that sees the goal before taking the last one tried."""
EPISODES_PER_HOUSE = 4
"""Online train episodes drawn in a house before the next (a new house costs its scene load and
goal sites, far more than a frame)."""


@dataclass
class VisionFrames:
    """Rendered frames: ``rgb`` (N, H, W, 3) uint8, ``depth`` (N, H, W, 1) float32, ``labels``
    (N, 8) the place of each category, ``goal`` (N,) the category of the episode's goal the
    pose was drawn around, ``distance`` (N,) its straight-line metres and ``recognition`` (N,)
    ObjRecogMap's label (:func:`~multion_agents.learned.learned_maps.recognition_label`)."""

    rgb: np.ndarray
    depth: np.ndarray
    labels: np.ndarray
    goal: np.ndarray
    distance: np.ndarray
    recognition: np.ndarray

    def __len__(self) -> int:
        return len(self.labels)


def view_labels(goal_mask: np.ndarray) -> np.ndarray:
    """The place (0-3) of each of the 8 categories in a ``goal_mask`` (H, W): 0 where none of
    its pixels shows, else the third of the width that holds the mean column of its pixels."""
    width = goal_mask.shape[1]
    labels = np.zeros(NUM_CATEGORIES, dtype=np.int64)
    for category in range(NUM_CATEGORIES):
        columns = np.nonzero(goal_mask == category + 1)[1]
        if len(columns):
            labels[category] = 1 + min(2, int(columns.mean() + 0.5) * 3 // width)
    return labels


def sample_frames(
    env_config: EnvConfig,
    count: int,
    seed: int,
    settings: VisionPretraining,
    split: str = "train",
    progress: bool = False,
) -> VisionFrames:
    """``count`` labelled frames of ``env_config``'s camera in houses of ``split``: poses on
    navigable cells within ``max_distance`` of a goal, every other one turned towards it (up to
    0.4 of the field of view off centre, at a cell with a line of sight to it where one of
    ``SIGHT_TRIES`` has one) and the rest at a random heading; a new episode every
    ``poses_per_scene`` poses, a new house every ``EPISODES_PER_HOUSE`` episodes."""
    dataset = env_config.dataset if split == "train" else None
    config = replace(
        env_config,
        sensors=("rgb", "depth", "goal_mask"),
        episodes_per_scene=EPISODES_PER_HOUSE,
        split=split,
        dataset=dataset,
    )
    hfov = config.camera.hfov_deg
    half_view = 0.4 * math.radians(hfov)
    rng = np.random.default_rng(seed)
    geometry = MapGeometry.from_env_config(config)
    rows: dict[str, list[np.ndarray]] = {"rgb": [], "depth": [], "labels": [], "recognition": []}
    goals: list[int] = []
    distances: list[float] = []
    env = MultiONEnv(config)
    bar = tqdm(total=count, desc="vision frames", unit="frame", disable=not progress)
    try:
        houses = random_goals(env, rng, seed)
        while len(goals) < count:
            grid, _, goal = next(houses)
            target = np.asarray(goal.position[:2], dtype=np.float64)
            cells = np.argwhere(grid.navigable)
            centres = grid.cell_to_world(cells[:, 0], cells[:, 1])
            gaps = np.hypot(*(centres - target).T)
            centres, gaps = (
                centres[gaps <= settings.max_distance],
                gaps[gaps <= settings.max_distance],
            )
            if len(centres) == 0:
                continue
            for index in range(min(settings.poses_per_scene, count - len(goals))):
                pick = int(rng.integers(len(centres)))
                yaw = float(rng.uniform(-math.pi, math.pi))
                if index % 2 == 0:  # a pose that sees the goal, where one is found
                    for _ in range(SIGHT_TRIES):
                        pick = int(rng.integers(len(centres)))
                        towards = math.atan2(
                            target[1] - centres[pick][1], target[0] - centres[pick][0]
                        )
                        yaw = towards + float(rng.uniform(-half_view, half_view))
                        if can_see(grid, centres[pick], yaw, target, hfov, settings.max_distance):
                            break
                position = centres[pick]
                observation = env.observe_pose(position, yaw)
                rows["rgb"].append(observation["rgb"])
                rows["depth"].append(observation["depth"])
                rows["labels"].append(view_labels(observation["goal_mask"]))
                rows["recognition"].append(
                    recognition_label(
                        torch.as_tensor(observation["goal_mask"][None]),
                        torch.as_tensor(observation["depth"][None]),
                        geometry,
                    ).numpy()
                )
                goals.append(goal.category)
                distances.append(float(gaps[pick]))
                bar.update(1)
    finally:
        bar.close()
        env.close()
    return VisionFrames(
        rgb=np.stack(rows["rgb"]),
        depth=np.stack(rows["depth"]).astype(np.float32),
        labels=np.stack(rows["labels"]),
        goal=np.asarray(goals, dtype=np.int64),
        distance=np.asarray(distances, dtype=np.float32),
        recognition=np.concatenate(rows["recognition"]).astype(np.int64),
    )


def goal_in_view(frames: VisionFrames) -> np.ndarray:
    """Per frame: whether the goal category it faces shows (its label)."""
    shown: np.ndarray = frames.labels[np.arange(len(frames)), frames.goal] > 0
    return shown
