"""Triangles of PyBullet's visual shapes, tessellated the way TinyRenderer tessellates them.

TinyRenderer (bullet3 ``TinyRendererVisualShapeConverter.cpp``, ``convertURDFToVisualShape``)
draws a box as PyBullet's textured unit cube scaled to the box (``ShapeData.h``), and turns a
cylinder, capsule or sphere into a convex shape tessellated with
``btShapeHull``: the shape's supporting vertices in 42 fixed directions
(``btShapeHull.cpp``, ``sUnitSpherePoints``), their convex hull, each vertex's normal its
normalised position and its texture coordinate spherical, ``(atan2(nx, nz) / 2π + 1/2,
ny / 2 + 1/2)``. A cylinder is first a 32-sided prism, so it is drawn with the few sides
those 42 directions pick. Meshes come from OBJ files (``Wavefront2GLInstanceGraphicsShape.cpp``):
the file's normals where it has them, else each triangle's own; texture coordinates where it
has them, else (0.5, 0.5); or from binary STL files (``LoadMeshFromSTL.h``). Hulls are triangulated here by Qhull, so a flat face may be split
along the other diagonal than Bullet's: positions and depth agree, shading may differ slightly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

GEOM_SPHERE, GEOM_BOX, GEOM_CYLINDER, GEOM_MESH, GEOM_CAPSULE = 2, 3, 4, 5, 7
"""PyBullet's visual geometry types (``p.GEOM_*``)."""
CYLINDER_STEPS = 32
"""Sides of the prism Bullet makes of a cylinder or capsule before its hull."""
CONVEX_MARGIN = 0.001
"""Bullet's collision margin on those convex shapes (``setMargin(0.001)``)."""

# btShapeHull's 42 sampling directions (bullet3 src/BulletCollision/CollisionShapes/btShapeHull.cpp)
UNIT_SPHERE_POINTS = np.array(
    [
        (0.000000, -0.000000, -1.000000), (0.723608, -0.525725, -0.447219),
        (-0.276388, -0.850649, -0.447219), (-0.894426, -0.000000, -0.447216),
        (-0.276388, 0.850649, -0.447220), (0.723608, 0.525725, -0.447219),
        (0.276388, -0.850649, 0.447220), (-0.723608, -0.525725, 0.447219),
        (-0.723608, 0.525725, 0.447219), (0.276388, 0.850649, 0.447219),
        (0.894426, 0.000000, 0.447216), (-0.000000, 0.000000, 1.000000),
        (0.425323, -0.309011, -0.850654), (-0.162456, -0.499995, -0.850654),
        (0.262869, -0.809012, -0.525738), (0.425323, 0.309011, -0.850654),
        (0.850648, -0.000000, -0.525736), (-0.525730, -0.000000, -0.850652),
        (-0.688190, -0.499997, -0.525736), (-0.162456, 0.499995, -0.850654),
        (-0.688190, 0.499997, -0.525736), (0.262869, 0.809012, -0.525738),
        (0.951058, 0.309013, 0.000000), (0.951058, -0.309013, 0.000000),
        (0.587786, -0.809017, 0.000000), (0.000000, -1.000000, 0.000000),
        (-0.587786, -0.809017, 0.000000), (-0.951058, -0.309013, -0.000000),
        (-0.951058, 0.309013, -0.000000), (-0.587786, 0.809017, -0.000000),
        (-0.000000, 1.000000, -0.000000), (0.587786, 0.809017, -0.000000),
        (0.688190, -0.499997, 0.525736), (-0.262869, -0.809012, 0.525738),
        (-0.850648, 0.000000, 0.525736), (-0.262869, 0.809012, 0.525738),
        (0.688190, 0.499997, 0.525736), (0.525730, 0.000000, 0.850652),
        (0.162456, -0.499995, 0.850654), (-0.425323, -0.309011, 0.850654),
        (-0.425323, 0.309011, 0.850654), (0.162456, 0.499995, 0.850654),
    ]
)  # fmt: skip


@dataclass(frozen=True)
class ShapeMesh:
    """One visual shape's triangles in its own frame, unindexed (3 vertices a triangle)."""

    positions: np.ndarray  # (N, 3) float64
    normals: np.ndarray  # (N, 3) float64, unit length (zero for degenerate triangles)
    uvs: np.ndarray  # (N, 2) float64
    texture: Path | None = None
    """The diffuse texture an OBJ's material names, if any."""


def hull_mesh(support_points: np.ndarray) -> ShapeMesh:
    """btShapeHull's tessellation of a convex shape given its supporting vertices."""
    from scipy.spatial import ConvexHull

    points = np.unique(np.round(support_points, 9), axis=0)
    hull = ConvexHull(points)
    triangles = []
    for simplex, equation in zip(hull.simplices, hull.equations, strict=True):
        a, b, c = points[simplex]
        # wind counter-clockwise seen from outside (TinyRenderer culls the others)
        if np.dot(np.cross(b - a, c - a), equation[:3]) < 0:
            simplex = simplex[[0, 2, 1]]
        triangles.append(simplex)
    return _convex_vertices(points[np.asarray(triangles).reshape(-1)])


def _convex_vertices(corners: np.ndarray) -> ShapeMesh:
    """A convex shape's triangle corners with Bullet's normals (the normalised position)
    and spherical texture coordinates."""
    normals = _normalised(corners)
    uvs = np.stack(
        [
            np.arctan2(normals[:, 0], normals[:, 2]) / (2 * math.pi) + 0.5,
            normals[:, 1] * 0.5 + 0.5,
        ],
        axis=1,
    )
    return ShapeMesh(corners, normals, uvs)


# PyBullet's textured unit cube (bullet3 examples/OpenGLWindow/ShapeData.h,
# cube_vertices_textured: position, normal, uv; cube_indices), which TinyRenderer scales to a
# box's half extents: flat faces, each face its own corner of the texture.
_CUBE = np.array(
    [
        (-1, -1, 1, 0, 0, 1, 0.75, 0.25),
        (1, -1, 1, 0, 0, 1, 1, 0.25),
        (1, 1, 1, 0, 0, 1, 1, 0),
        (-1, 1, 1, 0, 0, 1, 0.75, 0),
        (-1, -1, -1, 0, 0, -1, 0.5, 0.25),
        (1, -1, -1, 0, 0, -1, 0.25, 0.25),
        (1, 1, -1, 0, 0, -1, 0.25, 0),
        (-1, 1, -1, 0, 0, -1, 0.5, 0),
        (-1, -1, -1, -1, 0, 0, 0.5, 0),
        (-1, 1, -1, -1, 0, 0, 0.75, 0),
        (-1, 1, 1, -1, 0, 0, 0.75, 0.25),
        (-1, -1, 1, -1, 0, 0, 0.5, 0.25),
        (1, -1, -1, 1, 0, 0, 0.25, 0.5),
        (1, 1, -1, 1, 0, 0, 0.25, 0.25),
        (1, 1, 1, 1, 0, 0, 0, 0.25),
        (1, -1, 1, 1, 0, 0, 0, 0.5),
        (-1, -1, -1, 0, -1, 0, 0.25, 0.5),
        (-1, -1, 1, 0, -1, 0, 0.25, 0.25),
        (1, -1, 1, 0, -1, 0, 0.5, 0.25),
        (1, -1, -1, 0, -1, 0, 0.5, 0.5),
        (-1, 1, -1, 0, 1, 0, 0, 0),
        (-1, 1, 1, 0, 1, 0, 0, 0.25),
        (1, 1, 1, 0, 1, 0, 0.25, 0.25),
        (1, 1, -1, 0, 1, 0, 0.25, 0),
    ],
    dtype=np.float64,
)
_CUBE_INDICES = np.array(
    [0, 1, 2, 0, 2, 3, 6, 5, 4, 7, 6, 4, 10, 9, 8, 11, 10, 8, 12, 13, 14, 12, 14, 15,
     18, 17, 16, 19, 18, 16, 20, 21, 22, 20, 22, 23]
)  # fmt: skip


def box_mesh(full_extents: tuple[float, float, float]) -> ShapeMesh:
    """A box: PyBullet's textured cube scaled to its half extents."""
    corners = _CUBE[_CUBE_INDICES]
    half = np.asarray(full_extents, float) / 2
    return ShapeMesh(corners[:, 0:3] * half, corners[:, 3:6], corners[:, 6:8])


def cylinder_mesh(length: float, radius: float, capsule: bool = False) -> ShapeMesh:
    """A cylinder (or capsule) along z: Bullet's 32-sided prism (plus two poles for a
    capsule) as a btConvexHullShape, whose supporting vertex in direction d is the first
    vertex of largest d · v, pushed out by the margin along d."""
    angles = 2 * math.pi * np.arange(CYLINDER_STEPS) / CYLINDER_STEPS
    ring = np.stack([radius * np.sin(angles), radius * np.cos(angles)], axis=1)
    vertices = []
    for x, y in ring:
        vertices += [(x, y, length / 2), (x, y, -length / 2)]
    if capsule:
        vertices += [(0.0, 0.0, length / 2 + radius), (0.0, 0.0, -length / 2 - radius)]
    hull_vertices = np.asarray(vertices, float)
    return hull_mesh(_supporting(hull_vertices))


def sphere_mesh(radius: float) -> ShapeMesh:
    """A sphere (btSphereShape: its supporting vertex is the direction times the radius)."""
    return hull_mesh(UNIT_SPHERE_POINTS * radius)


def _supporting(vertices: np.ndarray) -> np.ndarray:
    dots = UNIT_SPHERE_POINTS.astype(np.float32) @ vertices.astype(np.float32).T
    first_best = np.argmax(dots, axis=1)  # argmax keeps the first of equals, like Bullet
    supported: np.ndarray = vertices[first_best] + CONVEX_MARGIN * UNIT_SPHERE_POINTS
    return supported


def _normalised(vectors: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(vectors, axis=1, keepdims=True)
    unit: np.ndarray = np.divide(vectors, length, out=np.zeros_like(vectors), where=length > 1e-12)
    return unit


def obj_mesh(path: Path, scale: tuple[float, float, float]) -> ShapeMesh:
    """The triangles of an OBJ file, scaled, as Bullet's loader reads them: polygons as fans,
    the file's normals if every vertex of a triangle has one, else the triangle's normal."""
    positions: list[tuple[float, float, float]] = []
    normals: list[tuple[float, float, float]] = []
    uvs: list[tuple[float, float]] = []
    corners: list[tuple[int, int, int]] = []  # (position, uv, normal) indices, -1 if none
    texture: Path | None = None
    for line in path.read_text(errors="replace").splitlines():
        parts = line.split()
        if not parts:
            continue
        head = parts[0]
        if head == "v":
            positions.append((float(parts[1]), float(parts[2]), float(parts[3])))
        elif head == "vn":
            normals.append((float(parts[1]), float(parts[2]), float(parts[3])))
        elif head == "vt":
            uvs.append((float(parts[1]), float(parts[2]) if len(parts) > 2 else 0.0))
        elif head == "f":
            face = [
                _face_corner(item, len(positions), len(uvs), len(normals)) for item in parts[1:]
            ]
            for k in range(1, len(face) - 1):
                corners += [face[0], face[k], face[k + 1]]
        elif head == "mtllib" and texture is None:
            texture = _material_texture(path.parent / " ".join(parts[1:]))
    index = np.asarray(corners, dtype=np.int64).reshape(-1, 3)
    vertex = np.asarray(positions, float)[index[:, 0]] * np.asarray(scale, float)
    if uvs:
        uv = np.where(index[:, 1:2] >= 0, np.asarray(uvs, float)[index[:, 1]], 0.0)
    else:
        uv = np.full((len(index), 2), 0.5)
    face_normals = np.cross(vertex[1::3] - vertex[0::3], vertex[2::3] - vertex[0::3])
    flat = np.repeat(_normalised(face_normals), 3, axis=0)
    if normals:
        given = np.asarray(normals, float)[index[:, 2]]
        has = (index[:, 2] >= 0).reshape(-1, 3).all(axis=1).repeat(3)
        normal = np.where(has[:, None], given, flat)
    else:
        normal = flat
    return ShapeMesh(vertex, normal, uv, texture)


def stl_mesh(path: Path, scale: tuple[float, float, float]) -> ShapeMesh | None:
    """A binary STL file as Bullet reads it (``LoadMeshFromSTL.h``): each facet's normal from
    the file for its three corners, texture coordinates (0.5, 0.5); None for a file Bullet
    refuses (its size does not match its triangle count, e.g. an ASCII STL)."""
    data = path.read_bytes()
    count = int.from_bytes(data[80:84], "little", signed=True) if len(data) >= 84 else 0
    if count <= 0 or len(data) != 84 + 50 * count:
        return None
    record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
    facets = np.frombuffer(data, dtype=record, count=count, offset=84)
    positions = facets["corners"].reshape(-1, 3).astype(np.float64) * np.asarray(scale, float)
    normals = np.repeat(facets["normal"].astype(np.float64), 3, axis=0)
    return ShapeMesh(positions, normals, np.full((len(positions), 2), 0.5))


def _face_corner(item: str, positions: int, uvs: int, normals: int) -> tuple[int, int, int]:
    """``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn`` as 0-based indices (negative ones count
    from the end, as OBJ says); -1 where absent."""
    fields = item.split("/")

    def index(k: int, count: int) -> int:
        if len(fields) <= k or not fields[k]:
            return -1
        value = int(fields[k])
        return value - 1 if value > 0 else count + value

    return index(0, positions), index(1, uvs), index(2, normals)


def _material_texture(mtl: Path) -> Path | None:
    """The first diffuse texture (``map_Kd``) of an MTL file, if it exists."""
    if not mtl.is_file():
        return None
    for line in mtl.read_text(errors="replace").splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0] == "map_Kd":
            candidate = mtl.parent / parts[-1]
            return candidate if candidate.is_file() else None
    return None
