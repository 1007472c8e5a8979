"""What the ``gl`` renderer draws, read from the PyBullet world it mirrors.

Every visual shape of every body PyBullet holds becomes vertices for OpenGL: the scene's
static bodies are baked into one list in world coordinates (uploaded once per scene); any
other body (goals, distractors: created per episode, moved between episodes) keeps its own
vertices in its link's frame and is drawn at the pose PyBullet gives it at each image. A
body without a visual shape, or whose colour is fully transparent, is not drawn, as in
TinyRenderer.

A vertex is 17 float32s: position (3), normal (3), texture coordinate (2), colour RGBA (4),
its texture's rectangle in the atlas (x, y, width, height in texels; width 0 for none) and
the body id, which becomes the segmentation value.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from multion.sim.bullet import pybullet as p
from multion.sim.gl.shapes import (
    GEOM_BOX,
    GEOM_CAPSULE,
    GEOM_CYLINDER,
    GEOM_MESH,
    GEOM_SPHERE,
    ShapeMesh,
    box_mesh,
    cylinder_mesh,
    obj_mesh,
    sphere_mesh,
    stl_mesh,
)

FLOATS_PER_VERTEX = 17
RECT_COLUMNS = slice(12, 16)


@dataclass
class ShapeVertices:
    """One visual shape's vertices (``FLOATS_PER_VERTEX`` columns) and its texture file."""

    body: int
    link: int
    vertices: np.ndarray  # (N, 17) float32, in the link's frame
    texture: Path | None


def body_ids(client: int) -> list[int]:
    return [
        p.getBodyUniqueId(i, physicsClientId=client)
        for i in range(p.getNumBodies(physicsClientId=client))
    ]


def body_shapes(client: int, body: int, texture: Path | None = None) -> list[ShapeVertices]:
    """The drawable visual shapes of ``body``, each in its link's frame. ``texture``: the
    image ``changeVisualShape`` gave the body (PyBullet does not report it back)."""
    shapes = []
    for data in p.getVisualShapeData(body, physicsClientId=client):
        _, link, geometry, dims, mesh_file, frame_pos, frame_orn, rgba = data[:8]
        if rgba[3] == 0:  # TinyRenderer skips invisible shapes
            continue
        mesh = tessellate(int(geometry), tuple(dims), mesh_file.decode(errors="replace"))
        if mesh is None:
            continue
        rotation = _rotation(frame_orn)
        positions = mesh.positions @ rotation.T + np.asarray(frame_pos)
        normals = mesh.normals @ rotation.T
        image = texture if texture is not None else mesh.texture
        shapes.append(
            ShapeVertices(
                body=body,
                link=int(link),
                vertices=_vertex_rows(positions, normals, mesh.uvs, rgba, body),
                texture=image,
            )
        )
    return shapes


def _vertex_rows(
    positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, rgba: tuple, body: int
) -> np.ndarray:
    rows = np.zeros((len(positions), FLOATS_PER_VERTEX), dtype=np.float32)
    rows[:, 0:3] = positions
    rows[:, 3:6] = normals
    rows[:, 6:8] = uvs
    rows[:, 8:12] = rgba
    rows[:, 16] = body
    return rows


@functools.lru_cache(maxsize=4096)
def tessellate(geometry: int, dims: tuple[float, ...], mesh_file: str) -> ShapeMesh | None:
    if geometry == GEOM_BOX:
        return box_mesh((dims[0], dims[1], dims[2]))
    if geometry in (GEOM_CYLINDER, GEOM_CAPSULE):
        return cylinder_mesh(dims[0], dims[1], capsule=geometry == GEOM_CAPSULE)
    if geometry == GEOM_SPHERE:
        return sphere_mesh(dims[0])
    if geometry == GEOM_MESH and mesh_file:
        path, scale = Path(mesh_file), (dims[0], dims[1], dims[2])
        if path.suffix.lower() == ".stl":
            return stl_mesh(path, scale)
        if path.suffix.lower() == ".obj":
            return obj_mesh(path, scale)
        raise ValueError(f"the gl renderer reads OBJ and STL meshes, not {path}")
    return None  # planes and heightfields: TinyRenderer draws neither


def _rotation(quaternion: tuple[float, ...]) -> np.ndarray:
    return np.asarray(p.getMatrixFromQuaternion(quaternion), dtype=np.float64).reshape(3, 3)


Transform = tuple[tuple[float, float, float], tuple[float, float, float, float]]


def inertial_inverse(client: int, body: int) -> Transform:
    """The transform from a body's centre of mass back to its base's link frame."""
    info = p.getDynamicsInfo(body, -1, physicsClientId=client)
    (x, y, z), (qx, qy, qz, qw) = p.invertTransform(info[3], info[4])
    return (x, y, z), (qx, qy, qz, qw)


def link_pose(
    client: int, body: int, link: int, base_offset: Transform | None = None
) -> np.ndarray:
    """The 4 x 4 world transform of a body's link frame (the frame its visual shapes are
    placed in): for the base, its centre of mass moved back by ``base_offset``
    (:func:`inertial_inverse`, looked up when not given)."""
    if link >= 0:
        state = p.getLinkState(body, link, physicsClientId=client)
        position, orientation = state[4], state[5]
    else:
        com, com_orn = p.getBasePositionAndOrientation(body, physicsClientId=client)
        offset = base_offset if base_offset is not None else inertial_inverse(client, body)
        position, orientation = p.multiplyTransforms(com, com_orn, offset[0], offset[1])
    matrix = np.eye(4)
    matrix[:3, :3] = _rotation(orientation)
    matrix[:3, 3] = position
    return matrix


def in_world(shape: ShapeVertices, pose: np.ndarray) -> np.ndarray:
    """The shape's vertices moved into the world by its link's ``pose``."""
    rows: np.ndarray = shape.vertices.copy()
    rows[:, 0:3] = shape.vertices[:, 0:3] @ pose[:3, :3].T + pose[:3, 3]
    rows[:, 3:6] = shape.vertices[:, 3:6] @ pose[:3, :3].T
    return rows


@dataclass
class Atlas:
    """Several texture images in one (H, W, 3) uint8 image, rows bottom first (as OpenGL
    reads them), and where each image lies: (x, y, width, height) in texels."""

    pixels: np.ndarray
    places: dict[Path, tuple[int, int, int, int]]


def build_atlas(images: Mapping[Path, np.ndarray], width: int = 2048) -> Atlas:
    """Shelf-pack ``images`` (each (h, w, 3) uint8, top row first, as files store them).

    Each is stored flipped (bottom row first), which is what TinyRenderer samples: it flips
    a texture on upload and reads texel ``(int(u * w), int(v * h))``."""
    width = max([width, *(image.shape[1] for image in images.values())])
    order = sorted(images, key=lambda path: (-images[path].shape[0], str(path)))
    places: dict[Path, tuple[int, int, int, int]] = {}
    x = y = shelf = 0
    for path in order:
        h, w = images[path].shape[:2]
        if x + w > width:
            x, y, shelf = 0, y + shelf, 0
        places[path] = (x, y, w, h)
        x, shelf = x + w, max(shelf, h)
    pixels = np.zeros((max(1, y + shelf), width, 3), dtype=np.uint8)
    for path, (x0, y0, w, h) in places.items():
        pixels[y0 : y0 + h, x0 : x0 + w] = images[path][::-1]
    return Atlas(pixels, places)


def load_image(path: Path) -> np.ndarray:
    """An image file as (h, w, 3) uint8 RGB."""
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"), dtype=np.uint8)
