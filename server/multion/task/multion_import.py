"""Import the original MultiON episode files (``MultiNav-v1``) onto the user's own scans.

The format, as the reference code reads it (saimwani/multiON at 2ba4d25:
``habitat/datasets/multi_nav/multi_nav_dataset.py`` ``from_json``,
``habitat/tasks/nav/multi_nav_task.py`` ``MultiGoalNavEpisode`` / ``MultiGoal``)::

    {"episodes": [{"episode_id": "0", "scene_id": "mp3d/<scan>/<scan>.glb",
                   "start_position": [x, y, z], "start_rotation": [x, y, z, w],
                   "info": {"geodesic_distance": d},
                   "goals": [{"object_category": "cylinder_red", "position": [x, y, z]}, ...],
                   "distractors": [...]}]}          # distractors: the 2022 challenge's files

Positions are in habitat's frame: y up, the agent looking along -z at rotation identity. Here
the world is z up with yaw measured from +x, so a point maps as ``(x, y, z) -> (x, -z, y)``, and
the start's yaw is the heading of the rotated -z axis (the released files do not keep the
quaternions at unit length: they are normalised first). Goal categories are matched by colour
name (the reference's order, ``habitat/core/env.py`` l. 252-253, differs from ours).

Each scan is converted once to a z-up OBJ beside the output file (``--up y`` for y-up GLBs such
as HM3D's or ones exported by habitat tools; ``--up z`` for scans already z-up, such as
Matterport3D's own meshes); the dataset's ``scene_id`` is that OBJ's absolute path. Every leg's
geodesic distance is measured again on the scan's navigable grid, as the env measures it, and
compared with the file's ``info.geodesic_distance`` (their total).
"""

from __future__ import annotations

import dataclasses
import gzip
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from multion.config.datasets import DatasetError, check_episode, save_dataset
from multion.config.episode import Episode, Goal
from multion.config.sim import NavGridConfig
from multion.sim.geodesic import FieldCache, geodesic_distance
from multion.sim.navgrid import NavGrid
from multion.sim.simulator import load_world, navgrid_for
from multion.sim.world import convert_mesh
from multion_client.constants import REFERENCE_CATEGORY_NAMES, REFERENCE_TO_CATEGORY

HABITAT_SCENE_PREFIX = "data/scene_datasets/"
"""Stripped from scene ids before joining them to the scenes directory, as habitat does
(``DEFAULT_SCENE_PATH_PREFIX``, ``habitat/datasets/pointnav/pointnav_dataset.py`` l. 22)."""
UP_AXES = ("y", "z")
Y_UP_TO_Z_UP = np.array(
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
"""``(x, y, z) -> (x, -z, y)``: habitat's (and glTF's) y-up frame to this project's z-up one."""


def habitat_to_world(point: Sequence[float]) -> tuple[float, float, float]:
    """A point of habitat's y-up frame in this project's z-up frame."""
    x, y, z = (float(v) for v in point)
    return (x, -z, y)


def world_to_habitat(point: Sequence[float]) -> tuple[float, float, float]:
    """The inverse of :func:`habitat_to_world`."""
    x, y, z = (float(v) for v in point)
    return (x, z, -y)


def yaw_from_rotation(quaternion: Sequence[float]) -> float:
    """The z-up yaw (radians from +x, in (-pi, pi]) of a habitat agent rotation ``[x, y, z, w]``:
    the direction of its forward axis (-z), normalised first."""
    q = np.asarray(quaternion, dtype=np.float64)
    norm = float(np.linalg.norm(q))
    if q.shape != (4,) or not np.isfinite(q).all() or norm < 1e-9:
        raise ValueError(f"start_rotation must be 4 finite numbers, not all 0, got {quaternion!r}")
    x, y, z, w = q / norm
    # the third column of the rotation matrix, negated: R @ (0, 0, -1)
    forward = (-(2 * (x * z + w * y)), -(2 * (y * z - w * x)), -(1 - 2 * (x * x + y * y)))
    fx, _, fz = forward
    if math.hypot(fx, fz) < 1e-6:
        raise ValueError(f"start_rotation {list(quaternion)} looks straight up or down")
    return math.atan2(-fz, fx)


def rotation_from_yaw(yaw: float, scale: float = 1.0) -> list[float]:
    """A habitat rotation ``[x, y, z, w]`` (times ``scale``) facing the z-up ``yaw``."""
    theta = yaw - math.pi / 2  # the rotation about habitat's +y that turns -z to the heading
    return [0.0, scale * math.sin(theta / 2), 0.0, scale * math.cos(theta / 2)]


def category_of(name: Any) -> int:
    """This project's category id of a MultiON goal name (``cylinder_<colour>``)."""
    names = [f"cylinder_{colour}" for colour in REFERENCE_CATEGORY_NAMES]
    if name not in names:
        raise ValueError(f"object_category {name!r} is not a MultiON cylinder ({', '.join(names)})")
    return REFERENCE_TO_CATEGORY[names.index(name)]


@dataclass(frozen=True)
class ImportResult:
    path: Path
    episodes: tuple[Episode, ...]
    skipped: tuple[str, ...]
    """``"<episode id>: <reason>"`` for each episode left out."""
    geodesic_errors: tuple[float, ...]
    """Per imported episode: the measured total geodesic minus the file's, metres."""
    scenes: dict[str, Path]
    """The file's scene id -> the converted OBJ."""


def read_multinav(path: Path) -> list[dict[str, Any]]:
    """The episode list of a MultiNav-v1 file (``.json`` or ``.json.gz``)."""
    try:
        raw = path.read_bytes()
        text = gzip.decompress(raw) if raw[:2] == b"\x1f\x8b" else raw
        data = json.loads(text)
    except (OSError, EOFError, ValueError) as error:
        raise DatasetError(f"{path}: not a readable MultiON episode file ({error})") from None
    episodes = data.get("episodes") if isinstance(data, dict) else None
    if not isinstance(episodes, list) or not episodes:
        raise DatasetError(f'{path}: "episodes" must be a non-empty list')
    return episodes


def convert_scene(source: Path, target: Path, up: str) -> Path:
    """``source`` (any mesh trimesh reads) as a z-up OBJ at ``target``, written atomically;
    reused when it is newer than the source."""
    if up not in UP_AXES:
        raise ValueError(f"up must be one of {UP_AXES}, got {up!r}")
    try:
        return convert_mesh(source, target, Y_UP_TO_Z_UP if up == "y" else None)
    except ValueError as error:
        raise DatasetError(f"could not read the scan {source}: {error}") from error


def scan_path(scene_id: str, scenes_dir: Path) -> Path:
    """Where habitat would look for a scene id under ``scenes_dir``."""
    relative = scene_id.removeprefix(HABITAT_SCENE_PREFIX)
    path = (scenes_dir / relative).resolve()
    if not path.is_relative_to(scenes_dir.resolve()):
        raise DatasetError(f"scene_id {scene_id!r} points outside --scenes {scenes_dir}")
    return path


def convert_episode(item: Mapping[str, Any], index: int, scene: Path) -> tuple[Episode, float]:
    """One file episode in this project's frame and categories, and its ``geodesic_distance``."""
    start = habitat_to_world(item["start_position"])
    goals = tuple(
        Goal(category_of(g["object_category"]), habitat_to_world(g["position"]))
        for g in item["goals"]
    )
    distractors = tuple(
        Goal(category_of(d["object_category"]), habitat_to_world(d["position"]))
        for d in item.get("distractors") or ()
    )
    episode = Episode(
        episode_id=str(item.get("episode_id", index)),
        scene_id=str(scene),
        start_position=start,
        start_yaw=round(yaw_from_rotation(item["start_rotation"]), 6),
        goals=goals,
        distractors=distractors,
    )
    info = item.get("info") or {}
    return episode, float(info.get("geodesic_distance", math.nan))


def measure_legs(
    grid: NavGrid, episode: Episode, fields: FieldCache, goal_radius: float
) -> list[float]:
    """start -> g1, g1 -> g2, ... on ``grid``, as the env measures them (to each goal's
    footprint); ``inf`` where a point is off the navigable grid."""
    points = [
        np.asarray(episode.start_position[:2]),
        *(np.asarray(g.position[:2]) for g in episode.goals),
    ]
    legs = []
    for before, goal in zip(points, episode.goals, strict=False):
        field = fields.get(grid, np.asarray(goal.position[:2]), goal_radius)
        legs.append(geodesic_distance(grid, field, before))
    return legs


def import_multion(
    path: Path,
    scenes_dir: Path,
    out: Path,
    up: str = "y",
    split: str = "val",
    navgrid: NavGridConfig = NavGridConfig(),
    goal_radius: float = 0.05,
) -> ImportResult:
    """Convert a MultiNav-v1 file and its scans (see the module docstring) and write ``out``."""
    items = read_multinav(path)
    scenes: dict[str, Path] = {}
    grids: dict[Path, NavGrid] = {}
    fields = FieldCache()
    episodes: list[Episode] = []
    skipped: list[str] = []
    errors: list[float] = []
    for index, item in enumerate(items):
        name = str(item.get("episode_id", index)) if isinstance(item, dict) else str(index)
        try:
            scene_id = str(item["scene_id"])
            if scene_id not in scenes:
                source = scan_path(scene_id, scenes_dir)
                if not source.is_file():
                    raise DatasetError(f"episode {name}: scan {source} not found (--scenes)")
                target = out.parent / "scenes" / f"{source.stem}.obj"
                scenes[scene_id] = convert_scene(source, target, up).resolve()
            episode, expected = convert_episode(item, index, scenes[scene_id])
        except (KeyError, TypeError, ValueError) as error:
            if isinstance(error, DatasetError):
                raise
            raise DatasetError(f"{path}: episode {name}: malformed ({error!r})") from None
        problem = check_episode(episode)
        if problem:
            raise DatasetError(f"{path}: episode {name}: {problem}")
        scene = scenes[scene_id]
        if scene not in grids:
            world = load_world(str(scene))
            try:
                grids[scene] = navgrid_for(str(scene), world, navgrid)
            finally:
                world.close()
        legs = measure_legs(grids[scene], episode, fields, goal_radius)
        if not all(math.isfinite(d) for d in legs):
            skipped.append(f"{name}: start or a goal is off the scan's navigable grid")
            continue
        episode = dataclasses.replace(episode, geodesic_distances=tuple(round(d, 4) for d in legs))
        if math.isfinite(expected):
            errors.append(sum(legs) - expected)
        episodes.append(episode)
    if not episodes:
        raise DatasetError(f"{path}: no episode could be imported ({'; '.join(skipped[:3])})")
    shapes = {(e.num_goals, len(e.distractors)) for e in episodes}
    if len(shapes) > 1:
        raise DatasetError(
            f"{path}: episodes have different (goals, distractors) counts {sorted(shapes)}; "
            "a dataset holds one task"
        )
    num_goals, num_distractors = shapes.pop()
    generator = {"imported_from": str(path), "format": "MultiNav-v1", "up": up}
    written = save_dataset(out, episodes, num_goals, split, generator, num_distractors)
    return ImportResult(written, tuple(episodes), tuple(skipped), tuple(errors), scenes)
