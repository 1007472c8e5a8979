"""Video frames (issue 53 item 4): every video of a run has one frame size, whatever the shape of
its house, and the map keeps the house's proportions."""

from __future__ import annotations

import numpy as np

from multion.config.episode import Episode, Goal
from multion.sim.simulator import Simulator
from multion.video.frames import FrameComposer
from multion.video.replay import StepView


def test_houses_of_every_shape_give_frames_of_one_size() -> None:
    sizes = set()
    sim = Simulator()
    try:
        for scene in ("house-00003", "house-00007", "house-00042"):  # wide, tall, square-ish
            grid = sim.load_scene(scene)
            rows, cols = grid.shape
            centre = (grid.origin[0] + cols * grid.cell_size / 2, grid.origin[1] + 1.0, 0.0)
            episode = Episode("e", scene, centre, 0.0, (Goal(0, centre),))
            composer = FrameComposer(episode, grid, (64, 64), "t", ("cylinder",), 10)
            view = StepView(
                step=0,
                action=None,
                rgb=np.zeros((64, 64, 3), np.uint8),
                depth=np.zeros((64, 64, 1), np.float32),
                position=np.asarray(centre),
                yaw=0.0,
                goals_found=0,
                distance_to_goal=1.0,
                found_correct=False,
                found_wrong=False,
                collided=False,
                metrics={},
            )
            frame = composer.frame(view)
            assert frame.shape[:2] == (composer.size[1], composer.size[0])
            sizes.add(composer.size)
    finally:
        sim.close()
    assert len(sizes) == 1, sizes  # were 954, 768 and 926 px wide for one run's episodes
