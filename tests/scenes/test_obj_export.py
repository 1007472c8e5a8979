"""Wavefront OBJ export: counts, outward winding, materials, atomic writes."""

from __future__ import annotations

import numpy as np
import pytest

from multion.common import files as atomic_files
from multion.scenes.house import generate_house
from multion.scenes.obj_export import export_obj
from multion.scenes.room import make_room


def parse_obj(path):
    """Vertices, triangles (0-based) and, per triangle, the material it uses."""
    vertices, faces, materials, current = [], [], [], None
    for line in path.read_text().splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            vertices.append([float(p) for p in parts[1:4]])
        elif parts[0] == "f":
            faces.append([int(p) - 1 for p in parts[1:4]])
            materials.append(current)
        elif parts[0] == "usemtl":
            current = parts[1]
    return np.array(vertices), np.array(faces), materials


def parse_mtl(path):
    colours, name = {}, None
    for line in path.read_text().splitlines():
        parts = line.split()
        if parts and parts[0] == "newmtl":
            name = parts[1]
        elif parts and parts[0] == "Kd":
            colours[name] = tuple(float(p) for p in parts[1:4])
    return colours


def test_round_trip_counts_and_outward_normals(tmp_path):
    layout = generate_house(3)
    path = export_obj(layout, tmp_path / "house.obj")
    assert path == tmp_path / "house.obj"
    vertices, faces, _ = parse_obj(path)
    n = len(layout.boxes)
    assert len(vertices) == 8 * n and len(faces) == 12 * n
    # Boxes are regrouped by material, so match them by (centre, size) in both directions.
    blocks = vertices.reshape(n, 8, 3)
    got = np.hstack([blocks.mean(1), np.ptp(blocks, axis=1)])
    want = np.array([[*b.center, *(2 * h for h in b.half_extents)] for b in layout.boxes])
    gap = np.abs(got[:, None] - want[None]).max(-1)
    assert gap.min(1).max() < 1e-5 and gap.min(0).max() < 1e-5
    for face in faces:
        assert len(set(face // 8)) == 1  # a triangle never mixes two boxes
        a, b, c = vertices[face]
        normal = np.cross(b - a, c - a)
        centre = vertices[8 * (face[0] // 8) : 8 * (face[0] // 8) + 8].mean(axis=0)
        assert np.linalg.norm(normal) > 0
        assert np.dot(normal, (a + b + c) / 3 - centre) > 0  # points away from the box centre


def test_materials_match_box_colours(tmp_path):
    layout = make_room(6, 4)
    path = export_obj(layout, tmp_path / "room.obj")
    text = path.read_text()
    assert "mtllib room.mtl" in text
    colours = parse_mtl(tmp_path / "room.mtl")
    _, faces, materials = parse_obj(path)
    assert set(materials) == set(colours)
    for k, box in enumerate(layout.boxes):
        assert colours[materials[12 * k]] == pytest.approx(box.rgba[:3], abs=1e-4)
        assert materials[12 * k].startswith(box.kind)
    # one "o" group per kind-colour: floor, wall, ceiling here
    assert text.count("\no ") == len(colours) == 3


def test_without_ceiling(tmp_path):
    layout = make_room(6, 4)
    vertices, faces, _ = parse_obj(export_obj(layout, tmp_path / "r.obj", include_ceiling=False))
    assert len(faces) == 12 * (len(layout.boxes) - 1)
    assert vertices[:, 2].max() == pytest.approx(2.6)  # walls' tops; the ceiling slab is gone


def test_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = export_obj(make_room(6, 4), tmp_path / "scene.obj")
    before = path.read_text()

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(atomic_files.os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        export_obj(make_room(3, 3), path)
    assert path.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.mtl", "scene.obj"]
