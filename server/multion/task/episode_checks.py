"""Checks of an episode a caller wrote: inline in a session config, a reset option, or an
:class:`~multion.config.episode.Episode` handed to the env.

Everything here is cheap (no scene is built), so the server runs it when a session is created
and refuses a bad episode before any simulator work, with a message that names the field
(``episodes[0].goals[1].category``) and what is allowed. What needs the scene itself (a goal
off the navigable grid, an unreachable goal) is checked by the env's ``reset``
(:func:`multion.task.sampling.check_on_grid`). No simulator is imported here: the server process
runs these checks.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from multion.config.episode import Episode, Goal
from multion.config.task import TaskConfig
from multion.scenes.registry import SceneIdError, check_scene_id, is_mesh_scene, room_extent
from multion.task.errors import BadEpisodeError, BadResetOptionError
from multion_client.constants import NUM_CATEGORIES

MAX_COORDINATE_M = 1000.0
"""No scene reaches this far from its origin (houses span tens of metres, rooms 50 m at most);
a coordinate beyond it is a mistake, and would make grid indices overflow."""


def check_caller_episodes(episodes: Sequence[Episode], task: TaskConfig, where: str) -> None:
    """:func:`check_caller_episode` for each, named ``where[i]``."""
    for index, episode in enumerate(episodes):
        check_caller_episode(episode, task, f"{where}[{index}]")


def check_caller_episode(episode: Episode, task: TaskConfig, where: str = "episode") -> None:
    """Raise :class:`BadEpisodeError` naming the first field of ``episode`` that ``task`` cannot
    play. A mesh ``scene_id`` must name a file: check first that the caller may read it."""
    _check_scene(episode.scene_id, f"{where}.scene_id")
    _check_count(episode.goals, task.num_goals, f"{where}.goals", "task.num_goals")
    _check_count(
        episode.distractors, task.num_distractors, f"{where}.distractors", "task.num_distractors"
    )
    extent = room_extent(episode.scene_id)
    _check_point(episode.start_position, extent, f"{where}.start_position")
    if not math.isfinite(episode.start_yaw):
        raise BadEpisodeError(
            f"{where}.start_yaw = {episode.start_yaw!r} is out of range: allowed a finite number "
            "(radians from +x)"
        )
    seen: dict[int, str] = {}
    for kind, goals in (("goals", episode.goals), ("distractors", episode.distractors)):
        for index, goal in enumerate(goals):
            name = f"{where}.{kind}[{index}]"
            _check_category(goal, name, seen)
            _check_point(goal.position, extent, f"{name}.position")
    distances = episode.geodesic_distances
    if distances and len(distances) != len(episode.goals):
        raise BadEpisodeError(
            f"{where}.geodesic_distances has {len(distances)} values; allowed none or one per "
            f"goal ({len(episode.goals)})"
        )
    for index, distance in enumerate(distances):
        if not (math.isfinite(distance) and distance >= 0):
            raise BadEpisodeError(
                f"{where}.geodesic_distances[{index}] = {distance!r} is out of range: allowed "
                "[0, inf), finite"
            )


def _check_scene(scene_id: str, where: str) -> None:
    try:
        check_scene_id(scene_id)
    except SceneIdError as error:
        raise BadEpisodeError(f"{where}: {error}") from None
    if is_mesh_scene(scene_id) and not Path(scene_id).is_file():
        raise BadEpisodeError(f"{where}: no mesh file {scene_id!r:.200} on this machine")


def _check_count(goals: Sequence[Goal], expected: int, where: str, setting: str) -> None:
    if len(goals) != expected:
        raise BadEpisodeError(
            f"{where} has {len(goals)} entries; allowed exactly {setting} = {expected}"
        )


def _check_category(goal: Goal, where: str, seen: dict[int, str]) -> None:
    if not 0 <= goal.category < NUM_CATEGORIES:
        raise BadEpisodeError(
            f"{where}.category = {goal.category!r:.40} is out of range: allowed an integer in "
            f"[0, {NUM_CATEGORIES - 1}]"
        )
    if goal.category in seen:
        raise BadEpisodeError(
            f"{where}.category = {goal.category} repeats {seen[goal.category]}.category: the "
            "goals and distractors of an episode have distinct categories"
        )
    seen[goal.category] = where


def _check_point(
    point: tuple[float, float, float], room: tuple[float, float] | None, where: str
) -> None:
    for axis, value in zip("xyz", point, strict=True):
        if not (math.isfinite(value) and abs(value) <= MAX_COORDINATE_M):
            raise BadEpisodeError(
                f"{where} {axis} = {value!r} is out of range: allowed [-{MAX_COORDINATE_M:g}, "
                f"{MAX_COORDINATE_M:g}] metres"
            )
    if room is not None:  # a room's free interior is known without building it
        width, depth = room
        x, y = point[0], point[1]
        if not (0 <= x <= width and 0 <= y <= depth):
            raise BadEpisodeError(
                f"{where} ({x:g}, {y:g}) is outside the room: allowed x in [0, {width:g}], "
                f"y in [0, {depth:g}] metres"
            )


RESET_OPTIONS: dict[str, tuple[type | tuple[type, ...], str]] = {
    "episode_index": (int, "an int"),
    "episode_id": (str, "a string"),
    "episode": ((Mapping, Episode), "an Episode map"),
}
"""What ``reset(options=...)`` accepts (at most one): an episode by its index in the dataset, by
its id, or inline; with their types."""


def check_reset_options(options: Mapping[str, Any]) -> None:
    """Raise :class:`BadResetOptionError` unless ``options`` holds at most one known reset option
    of the right type."""
    unknown = sorted(set(options) - set(RESET_OPTIONS))
    if unknown:
        raise BadResetOptionError(
            f"unknown reset option(s) {unknown}; reset options are {', '.join(RESET_OPTIONS)}"
        )
    if len(options) > 1:
        raise BadResetOptionError(
            f"give at most one of the reset options {', '.join(RESET_OPTIONS)}"
        )
    for name, value in options.items():
        kind, text = RESET_OPTIONS[name]
        if isinstance(value, bool) or not isinstance(value, kind):
            raise BadResetOptionError(f"reset option {name!r} must be {text}, got {value!r:.80}")
