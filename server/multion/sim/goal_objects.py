"""Real-object goals (MultiON 2.0's REAL-OBJECTS track, here from the models PyBullet ships).

The 2022 challenge's real objects (guitar, electric piano, basketball, toy train, teddy bear,
rocking horse, backpack, trolley bag) are downloads under their own terms; these eight come with
the pybullet wheel (``pybullet_data``, under the zlib licence of bullet3). Left out: the duck
(Collada's sample model, its own terms), the Stanford bunny (research use only), the bicycle
(CC BY-SA) and the domino and Laikago models (their own licence files); the other candidates with
one visual mesh are not everyday objects (cubes, planes, a stadium).

Each model is loaded once per world with its own colours and textures, turned upright
(``upright``: the model files of the teddy bear lie on their backs), scaled so that its largest
extent is ``size`` metres (0.3-0.9 m, like the challenge's objects), and stood on the floor. The
scaling is written into a copy of the URDF (:func:`scaled_urdf`): PyBullet's EGL plugin ignores
``loadURDF(globalScaling=...)``, so both renderers would otherwise draw different sizes. It
is visual only: collisions are filtered out, so it neither blocks the agent nor the rays that
build the navigable grid, like the cylinders. A goal's yaw is drawn per episode and goal from a
hash of the episode id (reproducible: the same episode shows the same poses).

Unseen objects (``unseen_train``, ``unseen_test``), beyond the 2022 challenge, as the 2023
edition's zero-shot classes: random shapes of ``pybullet_data/random_urdfs`` (procedurally made
for PyBullet), models 0-7 for training and 500-507 for testing, so an agent evaluated on
``unseen_test`` has never seen its goals.
"""

from __future__ import annotations

import functools
import math
import re
import tempfile
import xml.etree.ElementTree as ElementTree
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet_data

from multion.common.files import replacing
from multion.sim.bullet import c_output_silenced
from multion.sim.bullet import pybullet as p
from multion_client.constants import (
    OBJECT_CATEGORIES,
    UNSEEN_TEST_CATEGORIES,
    UNSEEN_TRAIN_CATEGORIES,
)


@dataclass(frozen=True)
class ObjectModel:
    urdf: str
    """Path inside ``pybullet_data``."""
    size: float
    """Largest extent once scaled, metres."""
    upright: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Euler angles (roll, pitch, yaw) that stand the model up."""


EVERYDAY_MODELS: dict[str, ObjectModel] = {
    "teddy_bear": ObjectModel("teddy_vhacd.urdf", 0.8, (math.pi / 2, 0.0, 0.0)),
    "soccer_ball": ObjectModel("soccerball.urdf", 0.4),
    "mug": ObjectModel("objects/mug.urdf", 0.35),
    "toy_car": ObjectModel("racecar/racecar.urdf", 0.7),
    "toy_robot": ObjectModel("r2d2.urdf", 0.9),
    "toy_rover": ObjectModel("husky/husky.urdf", 0.8),
    "toy_brick": ObjectModel("lego/lego.urdf", 0.4),
    "tray": ObjectModel("tray/tray_textured2.urdf", 0.6),
}
assert tuple(EVERYDAY_MODELS) == OBJECT_CATEGORIES
RANDOM_OBJECT_SIZE = 0.6
"""Largest extent of the unseen-object goals (``random_urdfs``), metres."""
MODELS: dict[str, ObjectModel] = {
    **EVERYDAY_MODELS,
    **{
        name: ObjectModel(f"random_urdfs/{name[7:]}/{name[7:]}.urdf", RANDOM_OBJECT_SIZE)
        for name in (*UNSEEN_TRAIN_CATEGORIES, *UNSEEN_TEST_CATEGORIES)
    },
}
"""Every object model by category name (the goal sets ``objects``, ``unseen_train`` and
``unseen_test``)."""
OBJECT_GOAL_SETS = ("objects", "unseen_train", "unseen_test")


def goal_yaw(episode_id: str, index: int) -> float:
    """The yaw of goal ``index`` (goals, then distractors) of an episode, radians in [0, 2 pi)."""
    return 2 * math.pi * (zlib.crc32(f"{episode_id}/{index}".encode()) / 2**32)


def _scaled(text: str, scale: float) -> str:
    # xacro's ``$(optenv NAME default)`` is left in the husky's URDF: keep the default
    text = re.sub(r"\$\(optenv \S+ ([^)]*)\)", r"\1", text)
    return " ".join(f"{float(v) * scale:.6g}" for v in text.split())


def body_bounds(body: int, client: int) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds ``(low, high)`` of every link of ``body``."""
    boxes = [
        p.getAABB(body, link, physicsClientId=client)
        for link in range(-1, p.getNumJoints(body, physicsClientId=client))
    ]
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


@functools.cache
def native_size(urdf: str, upright: tuple[float, float, float]) -> float:
    """The largest extent of a ``pybullet_data`` model as its file makes it, turned upright,
    measured in a client of its own (the EGL plugin keeps the first size it draws of a mesh
    file, so the renderer's client must only ever see the scaled model)."""
    client = p.connect(p.DIRECT)
    try:
        with c_output_silenced():  # URDFs without inertia make PyBullet complain
            body = p.loadURDF(str(Path(pybullet_data.getDataPath()) / urdf),
                              baseOrientation=p.getQuaternionFromEuler(upright),
                              useFixedBase=True, physicsClientId=client)  # fmt: skip
        low, high = body_bounds(body, client)
        return float(max(high - low))
    finally:
        p.disconnect(physicsClientId=client)


def scaled_urdf(model: ObjectModel, folder: Path | None = None) -> Path:
    """A copy of ``model``'s URDF with every length multiplied so that its largest extent is
    ``model.size`` (origins, mesh scales, boxes, cylinders, spheres) and file names made
    absolute; written once, atomically, to a cache folder."""
    scale = model.size / native_size(model.urdf, model.upright)
    data = Path(pybullet_data.getDataPath())
    source = data / model.urdf
    folder = folder or Path(tempfile.gettempdir()) / "multion-goal-objects"
    folder.mkdir(parents=True, exist_ok=True)
    # file names inside are absolute: each pybullet_data install gets its own copy, so a cache
    # written by another install (another virtualenv) is never read
    install = zlib.crc32(str(data).encode())
    path = folder / f"{source.stem}-{scale:.6f}-{install:08x}.urdf"
    if path.is_file():
        return path
    tree = ElementTree.parse(source)
    for element in tree.iter():
        if element.tag == "origin" and "xyz" in element.attrib:
            element.set("xyz", _scaled(element.attrib["xyz"], scale))
        elif element.tag == "mesh":
            element.set("scale", _scaled(element.attrib.get("scale", "1 1 1"), scale))
        elif element.tag == "box":
            element.set("size", _scaled(element.attrib["size"], scale))
        elif element.tag in ("cylinder", "sphere", "capsule"):
            for key in ("radius", "length"):
                if key in element.attrib:
                    element.set(key, _scaled(element.attrib[key], scale))
        if element.tag in ("mesh", "texture") and "filename" in element.attrib:
            element.set("filename", str(source.parent / element.attrib["filename"]))
    with replacing(path) as temporary:
        tree.write(temporary)
    return path
