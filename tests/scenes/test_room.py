"""The single empty room used by hand-computed tests."""

from __future__ import annotations

import pytest

from multion.scenes.room import WALL_THICKNESS, make_room


def xy(box):
    (x0, y0, _), (x1, y1, _) = box.min_corner, box.max_corner
    return x0, y0, x1, y1


def test_room_6x4_interior_is_exactly_the_rectangle():
    layout = make_room(6, 4)
    assert layout.scene_id == "room-6x4"
    (room,) = layout.rooms
    assert room.rect == (0.0, 0.0, 6.0, 4.0)
    assert layout.doors == ()
    walls = [b for b in layout.boxes if b.kind == "wall"]
    assert len(walls) == 4
    assert not [b for b in layout.boxes if b.kind == "furniture"]
    for wall in walls:
        x0, y0, x1, y1 = xy(wall)
        # No wall reaches into the open interior (0, 6) x (0, 4) …
        assert x1 <= 1e-9 or x0 >= 6 - 1e-9 or y1 <= 1e-9 or y0 >= 4 - 1e-9
        # … each is one wall thickness thin and stands on the floor up to 2.6 m.
        assert min(x1 - x0, y1 - y0) == pytest.approx(WALL_THICKNESS)
        assert wall.min_corner[2] == pytest.approx(0.0)
        assert wall.max_corner[2] == pytest.approx(2.6)


@pytest.mark.parametrize(("x", "y"), [(-0.01, 2), (6.01, 2), (3, -0.01), (3, 4.01), (-0.1, -0.1)])
def test_room_is_closed_just_outside_the_rectangle(x, y):
    walls = [xy(b) for b in make_room(6, 4).boxes if b.kind == "wall"]
    assert any(x0 <= x <= x1 and y0 <= y <= y1 for x0, y0, x1, y1 in walls)


def test_floor_and_ceiling_cover_the_room_and_its_walls():
    layout = make_room(10, 2.5)
    assert layout.scene_id == "room-10x2.5"
    (floor,) = [b for b in layout.boxes if b.kind == "floor"]
    (ceiling,) = [b for b in layout.boxes if b.kind == "ceiling"]
    t = WALL_THICKNESS
    assert xy(floor) == pytest.approx((-t, -t, 10 + t, 2.5 + t))
    assert floor.max_corner[2] == pytest.approx(0.0)
    assert xy(ceiling) == pytest.approx((-t, -t, 10 + t, 2.5 + t))
    assert ceiling.min_corner[2] == pytest.approx(2.6)
    assert layout.bounds[0][:2] == pytest.approx((-t, -t))


@pytest.mark.parametrize(("w", "d"), [(0, 4), (6, -1)])
def test_bad_room_sizes_raise(w, d):
    with pytest.raises(ValueError, match="positive"):
        make_room(w, d)
