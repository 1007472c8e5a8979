"""The gl renderer's tessellation (``multion.sim.gl.shapes``): what it reads from mesh files and
how it builds PyBullet's primitive shapes. No OpenGL needed."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from multion.sim.gl.scene import Atlas, build_atlas
from multion.sim.gl.shapes import box_mesh, cylinder_mesh, obj_mesh, sphere_mesh, stl_mesh


def test_a_box_is_pybullets_cube_scaled_with_flat_faces() -> None:
    mesh = box_mesh((2.0, 4.0, 6.0))
    assert len(mesh.positions) == 36  # 12 triangles
    assert np.allclose(np.abs(mesh.positions), [1.0, 2.0, 3.0])
    # each triangle's normal is its face's, and it faces outwards (counter-clockwise)
    a, b, c = mesh.positions[0::3], mesh.positions[1::3], mesh.positions[2::3]
    winding = np.cross(b - a, c - a)
    assert (np.einsum("ij,ij->i", winding, mesh.normals[0::3]) > 0).all()
    assert np.allclose(np.abs(mesh.normals).sum(axis=1), 1.0)


def test_hulls_are_closed_and_face_outwards() -> None:
    for mesh in (cylinder_mesh(1.0, 0.2), cylinder_mesh(1.0, 0.2, capsule=True), sphere_mesh(0.5)):
        a, b, c = mesh.positions[0::3], mesh.positions[1::3], mesh.positions[2::3]
        centre = mesh.positions.mean(axis=0)
        outward = np.einsum("ij,ij->i", np.cross(b - a, c - a), (a + b + c) / 3 - centre)
        assert (outward > 0).all()
        assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0)
    # a cylinder is the hull of Bullet's 32-sided prism, sampled in 42 directions
    low, high = (
        cylinder_mesh(1.0, 0.2).positions.min(axis=0),
        cylinder_mesh(1.0, 0.2).positions.max(axis=0),
    )
    assert np.allclose(high[2] - low[2], 1.0, atol=0.003) and high[0] <= 0.2 + 0.002


def test_an_obj_polygon_is_a_fan_with_the_files_normals_or_flat_ones(tmp_path: Path) -> None:
    path = tmp_path / "quad.obj"
    path.write_text(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 1\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3/2/1 4/1/1\n"  # a quad with normals: two triangles, a fan from 1
        "f -4 -2 -1\n"  # negative indices, no normals: the triangle's own
    )
    mesh = obj_mesh(path, (2.0, 1.0, 1.0))
    assert len(mesh.positions) == 9
    assert np.allclose(mesh.positions[3:6], [[0, 0, 0], [2, 1, 0], [0, 1, 0]])
    assert np.allclose(mesh.normals[:6], [0, 0, 1])
    assert np.allclose(mesh.uvs[1], [1, 1])
    assert np.allclose(mesh.normals[6:], [0, 0, 1])  # (0,0,0), (1,1,0), (0,1,0) wind upwards


def test_an_obj_names_its_materials_texture(tmp_path: Path) -> None:
    (tmp_path / "wood.png").write_bytes(b"not read here")
    (tmp_path / "box.mtl").write_text("newmtl m\nKd 1 1 1\nmap_Kd wood.png\n")
    (tmp_path / "box.obj").write_text("mtllib box.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    mesh = obj_mesh(tmp_path / "box.obj", (1.0, 1.0, 1.0))
    assert mesh.texture == tmp_path / "wood.png"
    assert np.allclose(mesh.uvs, 0.5)  # no texture coordinates: Bullet's (0.5, 0.5)


def test_a_binary_stl_is_read_and_an_ascii_one_refused_as_bullet_does(tmp_path: Path) -> None:
    facet = struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0)
    path = tmp_path / "part.stl"
    path.write_bytes(b"\0" * 80 + struct.pack("<i", 1) + facet)
    mesh = stl_mesh(path, (1.0, 2.0, 1.0))
    assert mesh is not None
    assert np.allclose(mesh.positions, [[0, 0, 0], [1, 0, 0], [0, 2, 0]])
    assert np.allclose(mesh.normals, [0, 0, 1]) and np.allclose(mesh.uvs, 0.5)
    ascii_stl = tmp_path / "ascii.stl"
    ascii_stl.write_text("solid x\nendsolid x\n" + " " * 100)
    assert stl_mesh(ascii_stl, (1.0, 1.0, 1.0)) is None


def test_the_atlas_stores_each_image_flipped_where_it_says() -> None:
    first = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    second = np.full((4, 2, 3), 200, dtype=np.uint8)
    atlas: Atlas = build_atlas({Path("a.png"): first, Path("b.png"): second}, width=8)
    x, y, w, h = atlas.places[Path("a.png")]
    assert (w, h) == (3, 2)
    assert np.array_equal(atlas.pixels[y : y + h, x : x + w], first[::-1])
    x, y, w, h = atlas.places[Path("b.png")]
    assert np.array_equal(atlas.pixels[y : y + h, x : x + w], second)


@pytest.mark.parametrize("suffix", [".ply", ".dae"])
def test_an_unread_mesh_format_is_named(suffix: str, tmp_path: Path) -> None:
    from multion.sim.gl.scene import tessellate

    with pytest.raises(ValueError, match="OBJ and STL"):
        tessellate(5, (1.0, 1.0, 1.0), str(tmp_path / f"mesh{suffix}"))
