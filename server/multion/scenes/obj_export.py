"""Write a scene layout as a Wavefront OBJ mesh with a ``.mtl`` material file beside it.

Every box becomes 8 vertices and 12 triangles, wound counter-clockwise when seen from outside
(so normals computed from the winding point outwards). Boxes that share a kind and a colour share
one material and one ``o`` group. Both files are written to a temporary file first and then
renamed, so a crash never leaves a half-written mesh behind.
"""

from __future__ import annotations

from pathlib import Path

from multion.common.files import write_atomically
from multion.scenes.layout import Box, Rgba, SceneLayout, vec3

# Corner k of a box: bit 0 picks x, bit 1 picks y (through _CORNERS), z from the second half.
_CORNERS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
# Two triangles per face, counter-clockwise seen from outside: bottom, top, -y, +y, -x, +x.
_TRIANGLES = [
    (0, 3, 2), (0, 2, 1),
    (4, 5, 6), (4, 6, 7),
    (0, 1, 5), (0, 5, 4),
    (3, 7, 6), (3, 6, 2),
    (0, 4, 7), (0, 7, 3),
    (1, 2, 6), (1, 6, 5),
]  # fmt: skip


def box_vertices(box: Box) -> list[tuple[float, float, float]]:
    """The 8 corners of ``box`` in the order the triangles above refer to."""
    lo, hi = box.min_corner, box.max_corner
    return [vec3(hi[a] if bit else lo[a] for a, bit in enumerate(c)) for c in _CORNERS]


def export_obj(layout: SceneLayout, path: str | Path, include_ceiling: bool = True) -> Path:
    """Write ``layout`` to ``path`` (an ``.obj``) and its materials beside it; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mtl_path = path.with_suffix(".mtl")

    groups: dict[tuple[str, Rgba], list[Box]] = {}  # dicts keep first-seen order
    for box in layout.boxes:
        if box.kind == "ceiling" and not include_ceiling:
            continue
        groups.setdefault((box.kind, box.rgba), []).append(box)
    names = {key: f"{key[0]}_{k:03d}" for k, key in enumerate(groups)}

    mtl = [f"# materials of scene {layout.scene_id}"]
    for (_, rgba), name in names.items():
        r, g, b, a = rgba
        mtl += [
            f"newmtl {name}",
            f"Kd {r:.4f} {g:.4f} {b:.4f}",
            "Ka 0 0 0",
            "Ks 0 0 0",
            f"d {a:.4f}",
            "illum 1",
            "",
        ]

    obj = [
        f"# scene {layout.scene_id}: {sum(map(len, groups.values()))} boxes, z up, metres",
        f"mtllib {mtl_path.name}",
    ]
    first = 1  # OBJ vertex numbers start at 1
    for key, boxes in groups.items():
        obj += [f"o {names[key]}", f"usemtl {names[key]}"]
        for box in boxes:
            obj += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in box_vertices(box)]
            obj += [f"f {first + i} {first + j} {first + k}" for i, j, k in _TRIANGLES]
            first += 8

    write_atomically(mtl_path, "\n".join(mtl) + "\n")
    write_atomically(path, "\n".join(obj) + "\n")
    return path
