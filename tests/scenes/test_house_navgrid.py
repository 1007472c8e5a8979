"""Houses as the simulator sees them: every door passable, navigable fraction, goals off furniture.

These build the navigable grid (a few seconds per house), so they use two houses of the splits.
"""

from __future__ import annotations

import numpy as np
import pytest

from multion.scenes.registry import layout_for
from multion.sim.simulator import Simulator
from multion.task.sampling import sample_episode

HOUSES = ["house-00061", "house-00075"]


@pytest.fixture(scope="module")
def grids():
    sim = Simulator()
    try:
        return {scene: sim.load_scene(scene) for scene in HOUSES}
    finally:
        sim.close()


@pytest.mark.parametrize("scene", HOUSES)
def test_every_door_is_passable_by_the_agent(grids, scene):
    grid, layout = grids[scene], layout_for(scene)
    for door in layout.doors:
        # the door's centre line, 0.4 m to either side of the wall, is on the navigable grid
        # (the largest connected region): the agent can walk from one room to the other
        cx, cy = door.center
        step = np.array([0.0, 0.4]) if door.axis == "x" else np.array([0.4, 0.0])
        points = np.array([(cx, cy) - step, (cx, cy), (cx, cy) + step])
        assert grid.is_navigable(points).all(), f"{scene}: door at {door.center} is blocked"


@pytest.mark.parametrize("scene", HOUSES)
def test_navigable_fraction_is_about_half(grids, scene):
    grid, layout = grids[scene], layout_for(scene)
    navigable = float(grid.navigable.sum()) * grid.cell_size**2
    fraction = navigable / float(layout.metadata["footprint_area"])
    assert 0.45 <= fraction <= 0.70, fraction


@pytest.mark.parametrize("scene", HOUSES)
def test_goals_never_stand_inside_furniture(grids, scene):
    grid, layout = grids[scene], layout_for(scene)
    blocking = [
        (b.min_corner, b.max_corner)
        for b in layout.boxes
        if b.kind == "furniture" and b.min_corner[2] < 0.75 and b.max_corner[2] > 0.05
    ]
    rng = np.random.default_rng(0)
    for k in range(10):
        episode = sample_episode(grid, scene, 3, rng, f"e{k}", num_distractors=2)
        assert episode is not None
        for goal in (*episode.goals, *episode.distractors):
            x, y = goal.position[:2]
            for (x0, y0, _), (x1, y1, _) in blocking:
                # the cylinder (radius 0.05) stands clear of every part below its top
                assert not (x0 - 0.05 < x < x1 + 0.05 and y0 - 0.05 < y < y1 + 0.05), (
                    f"{scene}: goal at {x:.2f}, {y:.2f} is inside furniture"
                )
