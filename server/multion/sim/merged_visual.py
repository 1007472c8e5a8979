"""A procedural scene's static boxes as one textured mesh, for the EGL renderer.

PyBullet's EGL plugin uploads every body's transform and issues one draw per visual shape on
each ``getCameraImage``; with Mesa on a CPU that per-body work, not the pixels, dominates a
house of ~500 boxes. Here the boxes become one mesh (an OBJ file) and one texture atlas (a
PNG): the plugin then draws one body. Collision bodies stay one per box, created before the
plugin loads, so the plugin never sees them (``PyBulletWorld.from_layout``); ray casts, the
navigable grid and TinyRenderer are untouched.

The mesh repeats what the plugin draws for a ``GEOM_BOX`` (``convertURDFToVisualShape2`` in
PyBullet's ``eglRendererVisualShapeConverter.cpp``): the box's 8 corners, each with the
normalised corner direction as its normal and a spherical texture coordinate. Colours are
baked into the atlas (texture × colour for textured boxes, a flat swatch for plain ones), so
the mesh is drawn white; a plain box samples the middle of its swatch at every corner.
"""

from __future__ import annotations

import hashlib
import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from multion.common.files import replacing, write_atomically
from multion.scenes.layout import Box
from multion.scenes.textures import SIZE_STEP, texture_image

MERGE_VERSION = 1
"""Bump when the mesh or atlas format changes (it names the cached files)."""
ATLAS_WIDTH = 2048
GUTTER = 16
"""Pixels of each texture's edge repeated around it, so that filtering and the first mipmap
levels do not pull in a neighbour's colour."""
SWATCH = 4
"""Side of a plain colour's square in the atlas (sampled only at its centre)."""

# The 8 corners of a unit box, x slowest; the 12 triangles (two per face, outward facing).
_CORNERS = np.array([(sx, sy, sz) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
_TRIANGLES = np.array(
    [
        (0, 1, 2), (1, 3, 2),  # x = -1
        (4, 6, 5), (6, 7, 5),  # x = +1
        (0, 4, 1), (4, 5, 1),  # y = -1
        (2, 3, 6), (3, 7, 6),  # y = +1
        (0, 2, 4), (2, 6, 4),  # z = -1
        (1, 5, 3), (5, 7, 3),  # z = +1
    ],
    dtype=np.int64,
)  # fmt: skip


@dataclass(frozen=True)
class MergedVisual:
    """The files of one scene's merged visual: an OBJ mesh and its texture atlas (PNG)."""

    mesh: Path
    atlas: Path
    boxes: int
    """Boxes merged into the mesh."""


def box_corners(box: Box) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(positions, normals, uvs)`` of a box's 8 corners as the EGL plugin makes them: world
    positions, the corner's direction from the centre as normal, and the spherical texture
    coordinates ``(atan2(nx, nz) / 2π + 1/2, ny / 2 + 1/2)``."""
    local = _CORNERS * np.asarray(box.half_extents, float)
    normals = local / np.linalg.norm(local, axis=1, keepdims=True)
    uvs = np.stack(
        [np.arctan2(normals[:, 0], normals[:, 2]) / (2 * math.pi) + 0.5, normals[:, 1] / 2 + 0.5],
        axis=1,
    )
    return local + np.asarray(box.center, float), normals, uvs


def _texture_key(box: Box) -> tuple:
    """What a box looks like: its texture image (pattern and face size, as the world picks
    them: floors their top, walls their long side) and its colour."""
    rgb = tuple(int(round(255 * c)) for c in box.rgba[:3])
    if not box.texture:
        return ("", 0, 0, rgb)
    hx, hy, hz = (2 * h for h in box.half_extents)
    size = (hx, hy) if box.kind == "floor" else (max(hx, hy), hz)
    return (box.texture, round(size[0] / SIZE_STEP), round(size[1] / SIZE_STEP), rgb)


def _tile(key: tuple) -> tuple[np.ndarray, tuple[int, int]]:
    """The (H, W, 3) uint8 pixels of one appearance, gutter included, and the (height,
    width) of its image without the gutter."""
    pattern, su, sv, rgb = key
    colour = np.asarray(rgb, float) / 255.0
    if not pattern:
        image = np.full((SWATCH, SWATCH, 3), rgb, dtype=np.uint8)
    else:
        grey = texture_image(pattern, su * SIZE_STEP, sv * SIZE_STEP).astype(float)
        image = np.clip(np.round(grey * colour), 0, 255).astype(np.uint8)
    # the image starts GUTTER pixels in; the tile is rounded up to whole GUTTER steps, so that
    # every image starts on the same 2^k texel grid as the atlas's mipmap levels
    h, w = image.shape[:2]
    bottom = -(h + GUTTER) % GUTTER + GUTTER
    right = -(w + GUTTER) % GUTTER + GUTTER
    return np.pad(image, ((GUTTER, bottom), (GUTTER, right), (0, 0)), mode="edge"), (h, w)


def build_atlas(boxes: tuple[Box, ...]) -> tuple[np.ndarray, list[tuple[float, ...]]]:
    """One image holding every appearance of ``boxes`` and, per box, where its appearance is:
    ``(u0, v0, u1, v1, plain)`` in texture coordinates (v up, PyBullet flips rows on upload);
    plain is 1.0 for a flat colour."""
    keys = sorted({_texture_key(b) for b in boxes}, key=lambda k: (k[0], k[1], k[2], k[3]))
    made = {key: _tile(key) for key in keys}
    tiles = {key: tile for key, (tile, _) in made.items()}
    sizes = {key: size for key, (_, size) in made.items()}
    # shelf packing, tallest first
    order = sorted(keys, key=lambda k: (-tiles[k].shape[0], -tiles[k].shape[1], k))
    places: dict[tuple, tuple[int, int]] = {}
    x = y = shelf = 0
    for key in order:
        h, w = tiles[key].shape[:2]
        if x + w > ATLAS_WIDTH:
            x, y, shelf = 0, y + shelf, 0
        places[key] = (x, y)
        x, shelf = x + w, max(shelf, h)
    height = y + shelf
    atlas = np.zeros((height, ATLAS_WIDTH, 3), dtype=np.uint8)
    for key, (x0, y0) in places.items():
        tile = tiles[key]
        atlas[y0 : y0 + tile.shape[0], x0 : x0 + tile.shape[1]] = tile
    regions: list[tuple[float, ...]] = []
    for box in boxes:
        key = _texture_key(box)
        x0, y0 = places[key]
        h, w = sizes[key]
        x0, y0 = x0 + GUTTER, y0 + GUTTER
        # image row r is texture v = 1 - r / height (rows are flipped on upload)
        regions.append(
            (
                x0 / ATLAS_WIDTH,
                1 - (y0 + h) / height,
                (x0 + w) / ATLAS_WIDTH,
                1 - y0 / height,
                0.0 if key[0] else 1.0,
            )
        )
    return atlas, regions


def mesh_text(boxes: tuple[Box, ...], regions: list[tuple[float, ...]]) -> str:
    """The OBJ text of all boxes, texture coordinates mapped into their atlas regions."""
    lines = ["# multion merged scene visual"]
    vt, vn, faces = [], [], []
    for k, (box, (u0, v0, u1, v1, plain)) in enumerate(zip(boxes, regions, strict=True)):
        positions, normals, uvs = box_corners(box)
        if plain:
            uvs = np.full_like(uvs, 0.5)
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in positions]
        vn += [f"vn {x:.6f} {y:.6f} {z:.6f}" for x, y, z in normals]
        vt += [f"vt {u0 + u * (u1 - u0):.7f} {v0 + v * (v1 - v0):.7f}" for u, v in uvs]
        for tri in _TRIANGLES + 1 + 8 * k:
            faces.append("f " + " ".join(f"{i}/{i}/{i}" for i in tri))
    return "\n".join(lines + vt + vn + faces) + "\n"


def merged_visual(boxes: tuple[Box, ...], folder: Path | None = None) -> MergedVisual:
    """The merged mesh and atlas of ``boxes``, written once to a cache folder (named by
    their content, written atomically) and shared by every process."""
    from PIL import Image

    folder = folder or Path(tempfile.gettempdir()) / "multion-merged"
    folder.mkdir(parents=True, exist_ok=True)
    digest = hashlib.sha256(f"{MERGE_VERSION}:{boxes!r}".encode()).hexdigest()[:20]
    mesh, atlas_path = folder / f"scene-{digest}.obj", folder / f"scene-{digest}.png"
    if not (mesh.is_file() and atlas_path.is_file()):
        atlas, regions = build_atlas(boxes)
        with replacing(atlas_path) as temporary:
            Image.fromarray(atlas).save(temporary, format="PNG")
        text = mesh_text(boxes, regions)
        write_atomically(mesh, text)
    return MergedVisual(mesh=mesh, atlas=atlas_path, boxes=len(boxes))
