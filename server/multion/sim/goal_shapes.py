"""The supplement's shape goals: 8 red shapes on thin cylindrical supports, as triangle meshes.

Paper, supplement ("Varying target object shapes"): "cone, cube, cylinder, frustum, joined
inverted frustums, sphere, tetrahedron and torus. All these objects have a horizontal
length/diameter of 0.4 m. They have the same red color and are all placed on the top of a thin
cylindrical support." The meshes are generated here, at build time, from ``size`` (the
horizontal extent) and ``support_height``; each goal is one mesh (support and shape together)
so that it is one body, one ``goal_mask`` value. Heights not given by the paper: the cone,
cube, cylinder, joined frustums and sphere are as tall as wide; the frustum is 3/4 as tall as
wide, narrowing to half its width; the tetrahedron is regular; the torus lies flat, its tube a
quarter of its width across. The default support (0.6 m) puts a 0.4 m shape's middle at 0.8 m,
near the camera's 0.88 m (the supplement: goals "close to camera height").

Every mesh is closed, with its triangles wound counter-clockwise seen from outside. The world
loads each from an OBJ file written once to a cache folder (:func:`goal_mesh_file`): PyBullet's
EGL plugin draws meshes from files only, not from vertices passed in memory.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from multion.common.files import write_atomically
from multion_client.constants import SHAPE_CATEGORIES

SEGMENTS = 24
"""Facets around a surface of revolution."""
SUPPORT_RADIUS = 0.02
"""Radius of the thin cylindrical support, metres."""


@dataclass(frozen=True)
class Mesh:
    vertices: np.ndarray  # (V, 3) float64, metres, z up, the support's foot at the origin
    indices: np.ndarray  # (T * 3,) int32

    def moved(self, dz: float) -> Mesh:
        return Mesh(self.vertices + np.array([0.0, 0.0, dz]), self.indices)

    @staticmethod
    def join(meshes: Sequence[Mesh]) -> Mesh:
        vertices, indices, offset = [], [], 0
        for mesh in meshes:
            vertices.append(mesh.vertices)
            indices.append(mesh.indices + offset)
            offset += len(mesh.vertices)
        return Mesh(np.concatenate(vertices), np.concatenate(indices).astype(np.int32))


def revolve(profile: Sequence[tuple[float, float]], closed: bool = False) -> Mesh:
    """The surface swept by the ``(radius, z)`` polyline ``profile`` around the z axis.

    Traversed from the bottom centre outwards and up to the top centre (or, ``closed``,
    counter-clockwise in the (r, z) plane), the triangles face outwards."""
    angles = np.linspace(0.0, 2 * math.pi, SEGMENTS, endpoint=False)
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    points = np.asarray(profile, dtype=np.float64)
    vertices = np.concatenate(
        [np.column_stack([r * ring, np.full(SEGMENTS, z)]) for r, z in points]
    )
    rows = len(points) if closed else len(points) - 1
    faces = []
    for i in range(rows):
        below, above = i * SEGMENTS, ((i + 1) % len(points)) * SEGMENTS
        for j in range(SEGMENTS):
            k = (j + 1) % SEGMENTS
            a, b, c, d = below + j, below + k, above + j, above + k
            faces += [(a, b, d), (a, d, c)]
    return Mesh(vertices, np.asarray(faces, dtype=np.int32).reshape(-1))


def convex(vertices: np.ndarray, faces: Sequence[Sequence[int]]) -> Mesh:
    """A convex polyhedron from its (planar, convex) faces, each wound to face outwards."""
    centre = vertices.mean(axis=0)
    triangles = []
    for face in faces:
        for k in range(1, len(face) - 1):
            tri = [face[0], face[k], face[k + 1]]
            a, b, c = vertices[tri]
            if np.dot(np.cross(b - a, c - a), a - centre) < 0:
                tri = [tri[0], tri[2], tri[1]]
            triangles.append(tri)
    return Mesh(vertices.astype(np.float64), np.asarray(triangles, dtype=np.int32).reshape(-1))


def _cone(s: float) -> Mesh:
    return revolve([(0.0, 0.0), (s / 2, 0.0), (0.0, s)])


def _cube(s: float) -> Mesh:
    h = s / 2
    corners = np.array(
        [(x, y, z) for z in (0.0, s) for y in (-h, h) for x in (-h, h)], dtype=np.float64
    )
    faces = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    return convex(corners, faces)


def _cylinder(s: float) -> Mesh:
    return revolve([(0.0, 0.0), (s / 2, 0.0), (s / 2, s), (0.0, s)])


def _frustum(s: float) -> Mesh:
    return revolve([(0.0, 0.0), (s / 2, 0.0), (s / 4, 0.75 * s), (0.0, 0.75 * s)])


def _joined_frustums(s: float) -> Mesh:
    """Two frustums joined at their narrow ends (an hourglass), as tall as wide."""
    return revolve([(0.0, 0.0), (s / 2, 0.0), (s / 5, s / 2), (s / 2, s), (0.0, s)])


def _sphere(s: float) -> Mesh:
    t = np.linspace(-math.pi / 2, math.pi / 2, SEGMENTS // 2 + 1)
    return revolve([(s / 2 * math.cos(a), s / 2 * (1 + math.sin(a))) for a in t])


def _tetrahedron(s: float) -> Mesh:
    r = s / math.sqrt(3)  # circumradius of the base triangle of side s
    base = [
        (r * math.cos(a), r * math.sin(a), 0.0) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)
    ]
    apex = (0.0, 0.0, s * math.sqrt(2 / 3))
    vertices = np.array([*base, apex], dtype=np.float64)
    return convex(vertices, [(0, 1, 2), (0, 1, 3), (1, 2, 3), (2, 0, 3)])


def _torus(s: float) -> Mesh:
    tube = s / 8
    t = np.linspace(0.0, 2 * math.pi, SEGMENTS // 2, endpoint=False)
    profile = [(s / 2 - tube + tube * math.cos(a), tube + tube * math.sin(a)) for a in t]
    return revolve(profile, closed=True)


SHAPES: dict[str, Callable[[float], Mesh]] = {
    "cone": _cone,
    "cube": _cube,
    "cylinder": _cylinder,
    "frustum": _frustum,
    "joined_frustums": _joined_frustums,
    "sphere": _sphere,
    "tetrahedron": _tetrahedron,
    "torus": _torus,
}
assert tuple(SHAPES) == SHAPE_CATEGORIES


def goal_mesh(category: int, size: float, support_height: float) -> Mesh:
    """Shape ``category`` (an index of ``SHAPE_CATEGORIES``), ``size`` metres across, on a
    support ``support_height`` metres tall; the support's foot at the origin."""
    shape = SHAPES[SHAPE_CATEGORIES[category]](size).moved(support_height)
    if support_height <= 0:
        return shape
    support = revolve(
        [(0.0, 0.0), (SUPPORT_RADIUS, 0.0), (SUPPORT_RADIUS, support_height), (0.0, support_height)]
    )
    return Mesh.join([support, shape])


def goal_mesh_file(
    category: int, size: float, support_height: float, folder: Path | None = None
) -> Path:
    """:func:`goal_mesh` as an OBJ file in the cache folder (written once, atomically)."""
    folder = folder or Path(tempfile.gettempdir()) / "multion-goal-shapes"
    folder.mkdir(parents=True, exist_ok=True)
    name = SHAPE_CATEGORIES[category]
    path = folder / f"{name}-{size:.3f}-{support_height:.3f}-{SEGMENTS}.obj"
    if path.is_file():
        return path
    mesh = goal_mesh(category, size, support_height)
    lines = [f"# {name} goal, {size} m across, on a {support_height} m support", f"o {name}"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in mesh.vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.indices.reshape(-1, 3)]
    write_atomically(path, "\n".join(lines) + "\n")
    return path
