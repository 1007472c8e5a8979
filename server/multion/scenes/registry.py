"""Scene ids, the train / val / test splits, and turning an id into a layout.

Accepted ids:

* ``house-NNNNN``: procedural house number N (any non-negative integer, usually 5 digits);
  the default splits use houses 0–60 (train), 61–71 (val) and 72–89 (test), the same counts
  as Matterport3D's 61 / 11 / 18 scenes.
* ``house-NNNNN-rK``: house number N built with exactly K rooms (1..16), e.g. hidden houses of a
  challenge that narrows their room range.
* ``room-WxD``: one empty W × D metre room, e.g. ``room-6x4`` or ``room-10x2.5`` (sides up to
  50 m).
* a path ending in ``.obj``, ``.glb``, ``.gltf`` or ``.ply``: a mesh scan, loaded elsewhere.
"""

from __future__ import annotations

import dataclasses
import functools
import re

from multion.config.errors import UsageError
from multion.config.ranges import ConfigError
from multion.config.scenes import GENERATOR_VERSION as GENERATOR_VERSION  # re-exported
from multion.config.scenes import SPLIT_SIZES, HouseConfig
from multion.scenes.house import generate_house
from multion.scenes.layout import SceneLayout
from multion.scenes.room import make_room
from multion_client.errors import InvalidConfig

MAX_ROOM_SIDE_M = 50.0
"""A ``room-WxD`` side is at most this (the grid, and so memory, grows with the room's area)."""
SIZED_HOUSE_REVISION = 1
"""Revision of the ``house-N-rK`` houses alone, in the grid cache's key: they can change while
the default houses (and ``GENERATOR_VERSION``) stay. 1: corner cuts keep 60 % of the footprint,
and grids take the layout's floor height (issue 33: small houses walked on their roofs)."""
MESH_SUFFIXES = (".obj", ".glb", ".gltf", ".ply")
MAX_SIZED_ROOMS = 16
"""``house-N-rK`` takes K in 1..this (the generator's calibrated maximum)."""
MAX_HOUSE_DIGITS = 18
"""A house number has at most this many digits: a seed of 64 bits (the leaderboard's hidden
houses are numbered from 10**9 to about 10**12), and no int() of a megabyte of digits."""

_HOUSE = re.compile(r"house-(\d+)")
_SIZED_HOUSE = re.compile(r"house-(\d+)-r([1-9]|1[0-6])")
_ROOM = re.compile(r"room-(\d+(?:\.\d+)?)x(\d+(?:\.\d+)?)")
_ACCEPTED = "'house-NNNNN' (e.g. house-00042), 'room-WxD' in metres (e.g. room-6x4, room-10x2.5)"
_ACCEPTED_ALL = (
    f"{_ACCEPTED}, 'house-NNNNN-rK' (K rooms, 1..{MAX_SIZED_ROOMS}) or a mesh file path ending "
    f"in {', '.join(MESH_SUFFIXES)}"
)


class SceneIdError(UsageError, InvalidConfig, ValueError):
    """A scene id of no accepted form, or out of its range; the message says what is allowed."""


def _first_seeds() -> dict[str, int]:
    """The first house number of each split: the splits are consecutive, disjoint ranges."""
    first, start = {}, 0
    for split, size in SPLIT_SIZES.items():
        first[split] = start
        start += size
    return first


HOUSE_CONFIG = HouseConfig()
"""The generator parameters of every ``house-N``: a house is a pure function of (N, these)."""


def house_parameters(scene_id: str) -> tuple[int, HouseConfig]:
    """The (seed, generator parameters) that build procedural house ``scene_id``."""
    match = _HOUSE.fullmatch(scene_id)
    if match is None:
        raise SceneIdError(f"{scene_id!r} is not a procedural house id ('house-NNNNN')")
    check_scene_id(scene_id)
    return int(match.group(1)), HOUSE_CONFIG


def house_id(seed: int) -> str:
    """The canonical id of house number ``seed``, e.g. ``house-00042``."""
    return f"house-{seed:05d}"


def sized_house_id(seed: int, rooms: int) -> str:
    """The id of house number ``seed`` built with exactly ``rooms`` rooms (1..16), e.g.
    ``house-1234567-r3``; used for the hidden houses of a challenge that narrows their range."""
    if not 1 <= rooms <= MAX_SIZED_ROOMS:
        raise SceneIdError(f"rooms must be in 1..{MAX_SIZED_ROOMS}, got {rooms}")
    return f"{house_id(seed)}-r{rooms}"


def scene_ids(split: str) -> list[str]:
    """The house ids of ``split`` ("train", "val" or "test")."""
    if split not in SPLIT_SIZES:
        raise ConfigError(f"unknown split {split!r}; valid splits are {', '.join(SPLIT_SIZES)}")
    start = _first_seeds()[split]
    return [house_id(seed) for seed in range(start, start + SPLIT_SIZES[split])]


def scene_split(scene_id: str) -> str | None:
    """The default split a scene belongs to, or None (rooms, meshes, houses beyond the splits)."""
    match = _HOUSE.fullmatch(scene_id)
    if match is None:
        return None
    seed = int(match.group(1))
    for split, start in _first_seeds().items():
        if start <= seed < start + SPLIT_SIZES[split]:
            return split
    return None


def is_sized_house(scene_id: str) -> bool:
    """True for ``house-N-rK`` ids (a house built with exactly K rooms)."""
    return _SIZED_HOUSE.fullmatch(scene_id) is not None


def is_mesh_scene(scene_id: str) -> bool:
    """True if ``scene_id`` is a path to a mesh file rather than a procedural scene."""
    return scene_id.lower().endswith(MESH_SUFFIXES)


def check_scene_id(scene_id: str) -> None:
    """Raise :class:`SceneIdError` unless ``scene_id`` has an accepted form and range.

    Cheap (no scene is built): the server checks a client's episodes with it before any
    simulator work. A mesh path passes here; whether its file may be read is the caller's check.
    """
    house = _HOUSE.fullmatch(scene_id) or _SIZED_HOUSE.fullmatch(scene_id)
    if house is not None:
        if len(house.group(1)) > MAX_HOUSE_DIGITS:
            raise SceneIdError(
                f"scene id {scene_id!r:.60}: a house number has at most {MAX_HOUSE_DIGITS} digits"
            )
        return
    if match := _ROOM.fullmatch(scene_id):
        width, depth = float(match.group(1)), float(match.group(2))
        if not (0 < width <= MAX_ROOM_SIDE_M and 0 < depth <= MAX_ROOM_SIDE_M):
            raise SceneIdError(
                f"scene id {scene_id!r:.60}: room width and depth must be in "
                f"(0, {MAX_ROOM_SIDE_M:g}] metres"
            )
        return
    if is_mesh_scene(scene_id):
        return
    if re.fullmatch(r"house-\d+-r\d+", scene_id):
        raise SceneIdError(
            f"scene id {scene_id!r:.60}: a house's room count K in 'house-NNNNN-rK' must be in "
            f"1..{MAX_SIZED_ROOMS}"
        )
    raise SceneIdError(f"unknown scene id {scene_id!r:.80}; accepted forms are {_ACCEPTED_ALL}")


def room_extent(scene_id: str) -> tuple[float, float] | None:
    """The (width, depth) of a ``room-WxD`` id, whose free interior is [0, W] x [0, D]; None for
    any other id."""
    match = _ROOM.fullmatch(scene_id)
    return None if match is None else (float(match.group(1)), float(match.group(2)))


@functools.lru_cache(maxsize=64)
def layout_for(scene_id: str) -> SceneLayout:
    """The layout of a procedural scene id (see the module docstring for the accepted forms);
    :class:`SceneIdError` for any other id (a mesh path included: it has no layout)."""
    if is_mesh_scene(scene_id):
        raise SceneIdError(
            f"scene id {scene_id!r} is a mesh file; it has no procedural layout (load the mesh)"
        )
    check_scene_id(scene_id)
    if _HOUSE.fullmatch(scene_id):
        seed, config = house_parameters(scene_id)
        return generate_house(seed, config, scene_id=scene_id)
    if match := _SIZED_HOUSE.fullmatch(scene_id):
        rooms = int(match.group(2))
        config = dataclasses.replace(HOUSE_CONFIG, min_rooms=rooms, max_rooms=rooms)
        return generate_house(int(match.group(1)), config, scene_id=scene_id)
    extent = room_extent(scene_id)
    assert extent is not None  # check_scene_id let through houses, rooms and meshes only
    return make_room(*extent, scene_id=scene_id)
