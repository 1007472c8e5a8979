"""The navigable grid: known bounds in an empty room, and mesh and procedural paths agreeing."""

import numpy as np
import pytest

from multion.config.sim import NavGridConfig
from multion.scenes.obj_export import export_obj
from multion.scenes.registry import layout_for
from multion.sim.geodesic import distance_field, geodesic_distance
from multion.sim.navgrid import build_navgrid
from multion.sim.simulator import Simulator
from multion.sim.world import PyBulletWorld


def navigable_points(grid):
    rows, cols = np.nonzero(grid.navigable)
    return grid.cell_to_world(rows, cols)


def test_empty_room_bounds_are_eroded_by_the_agent_radius():
    grid = Simulator().load_scene("room-6x4")
    pts = navigable_points(grid)
    assert pts[:, 0].min() == pytest.approx(0.1) and pts[:, 0].max() == pytest.approx(5.9)
    assert pts[:, 1].min() == pytest.approx(0.1) and pts[:, 1].max() == pytest.approx(3.9)
    assert grid.floor_z == pytest.approx(0.0)
    assert grid.navigable.sum() == pytest.approx(117 * 77)


def test_geodesic_distance_in_open_space_is_euclidean():
    grid = Simulator().load_scene("room-6x4")
    field = distance_field(grid, np.array([1.0, 1.0]))
    assert geodesic_distance(grid, field, np.array([5.0, 1.0])) == pytest.approx(4.0, abs=0.03)
    assert geodesic_distance(grid, field, np.array([4.0, 3.0])) == pytest.approx(
        np.hypot(3, 2), abs=0.05
    )
    assert geodesic_distance(grid, field, np.array([0.02, 1.0])) == np.inf  # too close to the wall


def test_geodesic_goes_around_walls_in_a_house():
    sim = Simulator()
    grid = sim.load_scene("house-00061")
    pts = navigable_points(grid)
    rng = np.random.default_rng(0)
    a, b = pts[rng.integers(len(pts), size=2)]
    field = distance_field(grid, a)
    # never shorter than the straight line
    assert geodesic_distance(grid, field, b) >= np.hypot(*(a - b)) - 0.05
    # the house is one connected region and big enough for 2-20 m episodes
    reach = field[grid.navigable]
    assert np.isfinite(reach).all() and reach.max() > 8.0


@pytest.mark.parametrize("scene_id", ["house-00061", "house-00003"])
def test_mesh_scene_grid_matches_procedural_grid(tmp_path, scene_id):
    layout = layout_for(scene_id)
    procedural = build_navgrid(PyBulletWorld.from_layout(layout), NavGridConfig())
    path = export_obj(layout, tmp_path / f"{scene_id}.obj")
    mesh_world = PyBulletWorld.from_mesh(path)
    mesh = build_navgrid(mesh_world, NavGridConfig())  # floor height found from the mesh itself
    assert mesh.floor_z == pytest.approx(0.0, abs=0.01)
    # same cell alignment; Bullet's mesh bounds may add a margin column, so compare the overlap
    assert mesh.origin == pytest.approx(procedural.origin)
    rows = min(mesh.shape[0], procedural.shape[0])
    cols = min(mesh.shape[1], procedural.shape[1])
    a, b = mesh.navigable[:rows, :cols], procedural.navigable[:rows, :cols]
    assert a.sum() == mesh.navigable.sum() and b.sum() == procedural.navigable.sum()
    inter = (a & b).sum()
    union = (a | b).sum()
    assert inter / union >= 0.95


def test_bad_mesh_files_get_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        PyBulletWorld.from_mesh(tmp_path / "missing.obj")
    with pytest.raises(ValueError, match="unsupported mesh format"):
        PyBulletWorld.from_mesh(tmp_path / "scene.fbx")
