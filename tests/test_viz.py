"""Top-down scene pictures."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image, ImageDraw

from multion.scenes.room import make_room
from multion.scenes.viz import (
    BLOCKED,
    FOOTER_MARGIN,
    NAVIGABLE,
    TEXT,
    PictureFrame,
    label_font,
    picture_frame,
    scene_picture,
    world_to_pixel,
)


def colour_count(image: Image.Image, rgb: tuple[int, int, int]) -> int:
    return int((np.asarray(image) == rgb).all(-1).sum())


def test_picture_size_and_both_light_and_dark_cells() -> None:
    nav = np.zeros((80, 120), bool)  # 4 m high, 6 m wide at 0.05 m cells
    nav[20:60, 20:100] = True
    image = scene_picture(None, nav, origin=(0.0, 0.0), cell_size=0.05, pixels_per_metre=40)
    assert image.width == 240 and 160 < image.height < 220  # the plan, then the scale bar
    plan = image.crop((0, 0, 240, 160))
    assert image.mode == "RGB"
    assert colour_count(plan, NAVIGABLE) + colour_count(plan, BLOCKED) == 240 * 160
    assert colour_count(plan, NAVIGABLE) == 40 * 80 * 4


def test_the_scale_bar_and_id_are_drawn_outside_the_plan_and_whole() -> None:
    """Issue 42: they were drawn over the house, and a narrow house cut its id short."""
    layout = make_room(1.5, 4, scene_id="hidden-0123456789abcdef-house-17")
    nav = np.ones((85, 35), bool)  # x from -0.1 to 1.65, y from -0.1 to 4.15
    image = scene_picture(layout, nav, (-0.1, -0.1), 0.05, 40)
    frame = picture_frame(nav, (-0.1, -0.1), 0.05, 40)
    plan_width, plan_height = frame.image_size
    plan = np.asarray(image)[:plan_height, :plan_width]
    white, text = (plan == (255, 255, 255)).all(-1), (plan == TEXT).all(-1)
    assert not white.any() and not text.any()  # no label patch, no text on the plan
    footer = np.asarray(image)[plan_height:]
    inked = np.nonzero((footer == TEXT).all(-1).any(0))[0]
    assert inked.size and inked.min() >= FOOTER_MARGIN - 1
    assert inked.max() <= image.width - FOOTER_MARGIN  # nothing cut at the right edge
    font = label_font(frame)
    probe = ImageDraw.Draw(image)
    left, _, right, _ = probe.textbbox((0, 0), layout.scene_id, font=font)
    assert image.width >= right - left + 2 * FOOTER_MARGIN > plan_width  # widened for the id


def test_high_y_is_at_the_top_of_the_picture() -> None:
    nav = np.zeros((40, 40), bool)
    nav[30:, :] = True  # rows with the largest y
    pixels = np.asarray(scene_picture(None, nav, (0.0, 0.0), 0.1, 20))
    assert (pixels[5, 70] == NAVIGABLE).all()  # near the top (right of the scale bar)
    assert (pixels[70, 70] == BLOCKED).all()  # near the bottom


def test_layout_walls_are_drawn_where_they_are() -> None:
    layout = make_room(6, 4)
    nav = np.ones((90, 130), bool)  # x from -0.25 to 6.25, y from -0.25 to 4.25
    image = scene_picture(layout, nav, (-0.25, -0.25), 0.05, 40)
    frame = picture_frame(nav, (-0.25, -0.25), 0.05, 40)
    pixels = np.asarray(image)
    wall_x, wall_y = world_to_pixel(-0.07, 2.0, frame)  # inside the west wall
    assert (pixels[int(wall_y), int(wall_x)] != NAVIGABLE).any()
    mid_x, mid_y = world_to_pixel(3.0, 2.0, frame)  # the empty room centre
    assert (pixels[int(mid_y), int(mid_x)] == NAVIGABLE).all()


def test_world_to_pixel_corners() -> None:
    frame = picture_frame(np.ones((40, 60), bool), (1.0, 2.0), 0.1, 10)
    assert frame.image_size == (60, 40)
    assert world_to_pixel(1.0, 2.0, frame) == pytest.approx((0.0, 40.0))  # lower-left
    assert world_to_pixel(7.0, 6.0, frame) == pytest.approx((60.0, 0.0))  # upper-right


def test_rejects_non_2d_grids() -> None:
    with pytest.raises(ValueError, match="2-D"):
        scene_picture(None, np.ones((3, 3, 3), bool), (0, 0), 0.05)


@pytest.mark.parametrize("scene, ppm", [("house-00007", 10.0), ("house-00007", 40.0)])
def test_room_labels_stay_inside_their_room_and_the_picture(scene: str, ppm: float) -> None:
    """Issue 53 item 4: a label wider than its room ("living room" in a 2.5 m room on a video
    map) was cut at the picture's edge or spilled over walls, doorways and paths; now it is
    wrapped, smaller or shortened, or the room is left unlabelled."""

    from multion.scenes.registry import layout_for
    from multion.scenes.viz import picture_frame, room_labels

    layout = layout_for(scene)
    (x0, y0, _), (x1, y1, _) = layout.bounds
    grid = np.zeros((round((y1 - y0) / 0.05), round((x1 - x0) / 0.05)), dtype=bool)
    frame = picture_frame(grid, (x0, y0), 0.05, ppm)
    draw = ImageDraw.Draw(Image.new("RGB", frame.image_size))
    labels = room_labels(draw, layout, frame, label_font(frame))
    assert len(labels) >= len(layout.rooms) // 2
    width, height = frame.image_size
    margin = 3.0  # the label's patch keeps off the walls and doorways
    for text, box in labels:
        left, top, right, bottom = box
        assert 0 <= left and right <= width and 0 <= top and bottom <= height, text
        inside = any(
            rx0 + margin - 0.01 <= left
            and right <= rx1 - margin + 0.01
            and ry0 + margin - 0.01 <= top
            and bottom <= ry1 - margin + 0.01
            for rx0, ry0, rx1, ry1 in (_pixels(r.rect, frame) for r in layout.rooms)
        )
        assert inside, f"{text!r} at {box} is not inside a room"


def _pixels(rect: tuple[float, float, float, float], frame: PictureFrame) -> tuple[float, ...]:
    (a, b), (c, d) = (
        world_to_pixel(rect[0], rect[3], frame),
        world_to_pixel(rect[2], rect[1], frame),
    )
    return (a, b, c, d)
