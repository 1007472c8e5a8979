"""Scene colours: muted walls and floors, and furniture that may look like a goal.

The goal objects are pure red, green, blue, cyan, magenta, yellow, black and white cylinders.
Floors, walls and most materials go through :func:`muted`: saturation at most 0.5 and value
(brightest channel) in [0.25, 0.78], at least 0.22 (largest per-channel difference) from all eight
goal colours. Some furniture is painted in :data:`BRIGHT_COLOURS` instead (:func:`bright`):
saturated colours close to the goals' (a red sofa, a blue rug, a white fridge), so recognising a
goal takes more than a colour threshold; they still stay ``GOAL_MARGIN`` away from every goal.
"""

from __future__ import annotations

import colorsys

import numpy as np

from multion.scenes.layout import Rgba

MAX_SATURATION = 0.5
MIN_VALUE = 0.25
MAX_VALUE = 0.78

# Per room type: (floor colour, wall colour) before per-seed variation.
ROOM_COLOURS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "living_room": ((0.62, 0.47, 0.33), (0.78, 0.74, 0.64)),  # oak, warm beige
    "kitchen": ((0.66, 0.64, 0.58), (0.70, 0.75, 0.64)),  # stone tiles, pale sage
    "bedroom": ((0.52, 0.39, 0.29), (0.68, 0.64, 0.74)),  # walnut, dusty lavender
    "bathroom": ((0.48, 0.52, 0.55), (0.62, 0.72, 0.72)),  # slate, pale aqua grey
    "dining_room": ((0.56, 0.40, 0.32), (0.78, 0.70, 0.58)),  # cherry, sand
    "office": ((0.45, 0.45, 0.48), (0.66, 0.69, 0.74)),  # grey carpet, grey blue
    "hallway": ((0.70, 0.58, 0.44), (0.74, 0.72, 0.68)),  # light oak, greige
    "room": ((0.60, 0.55, 0.48), (0.74, 0.72, 0.68)),  # the plain test room
}
CEILING = (0.78, 0.77, 0.74)

# Per room type: the floor and wall textures a room may get (one is drawn per room).
ROOM_TEXTURES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "living_room": (("planks",), ("plaster", "stripes")),
    "kitchen": (("tiles",), ("plaster", "small_tiles")),
    "bedroom": (("planks", "carpet"), ("stripes", "plaster")),
    "bathroom": (("small_tiles",), ("small_tiles", "plaster")),
    "dining_room": (("planks", "tiles"), ("plaster", "stripes")),
    "office": (("carpet",), ("plaster",)),
    "hallway": (("planks", "tiles"), ("plaster",)),
}

# Furniture materials.
MATERIALS: dict[str, tuple[float, float, float]] = {
    "wood_light": (0.72, 0.60, 0.45),
    "wood_mid": (0.58, 0.44, 0.30),
    "wood_dark": (0.40, 0.30, 0.22),
    "fabric_blue": (0.42, 0.48, 0.58),
    "fabric_olive": (0.52, 0.54, 0.40),
    "fabric_rust": (0.62, 0.45, 0.38),
    "fabric_mauve": (0.58, 0.48, 0.55),
    "fabric_sand": (0.74, 0.68, 0.56),
    "linen": (0.76, 0.74, 0.68),
    "metal": (0.55, 0.56, 0.58),
    "ceramic": (0.78, 0.78, 0.75),
    "stone": (0.42, 0.42, 0.44),
    "screen": (0.26, 0.27, 0.30),
    "foliage": (0.42, 0.52, 0.36),
    "glass": (0.55, 0.62, 0.62),
    "cardboard": (0.62, 0.50, 0.34),
}
FABRICS = ("fabric_blue", "fabric_olive", "fabric_rust", "fabric_mauve", "fabric_sand")
WOODS = ("wood_light", "wood_mid", "wood_dark")

# Saturated paints and fabrics close to (but never exactly) the goal colours: a red sofa, a blue
# rug, a white fridge, a black screen, a yellow stool. They are not muted, so a recogniser that
# thresholds colours meets false positives, as it would in a real home. Each stays at least
# ``GOAL_MARGIN`` (largest per-channel difference) from every goal colour, so goals keep their
# exact colours and the two can still be told apart by a careful look; only white paint can
# render as pure white (its channels saturate under the brightest lights), and then only its
# shape tells it from a white goal.
GOAL_MARGIN = 0.08
BRIGHT_COLOURS: dict[str, tuple[float, float, float]] = {
    "paint_red": (0.82, 0.10, 0.08),
    "paint_green": (0.12, 0.70, 0.18),
    "paint_blue": (0.10, 0.18, 0.80),
    "paint_cyan": (0.12, 0.78, 0.82),
    "paint_magenta": (0.78, 0.12, 0.70),
    "paint_yellow": (0.90, 0.82, 0.10),
    "paint_black": (0.09, 0.09, 0.10),
    "paint_white": (0.91, 0.91, 0.89),
}
BRIGHT = tuple(BRIGHT_COLOURS)


def muted(rgb: tuple[float, float, float], alpha: float = 1.0) -> Rgba:
    """Clamp a colour into the safe range (see the module docstring) and add alpha."""
    h, s, v = colorsys.rgb_to_hsv(*(float(c) for c in rgb))
    r, g, b = colorsys.hsv_to_rgb(h, min(s, MAX_SATURATION), min(max(v, MIN_VALUE), MAX_VALUE))
    return (round(r, 4), round(g, 4), round(b, 4), alpha)


def varied(rgb: tuple[float, float, float], rng: np.random.Generator, amount: float = 0.04) -> Rgba:
    """A slightly different shade of ``rgb`` (per-channel noise of ±amount), still safe."""
    noise = rng.uniform(-amount, amount, size=3)
    r, g, b = (float(c) for c in np.clip(np.asarray(rgb) + noise, 0.0, 1.0))
    return muted((r, g, b))


def bright(rgb: tuple[float, float, float], rng: np.random.Generator, amount: float = 0.03) -> Rgba:
    """A shade of a saturated colour, kept ``GOAL_MARGIN`` away from every goal colour."""
    noise = rng.uniform(-amount, amount, size=3)
    c = np.clip(np.asarray(rgb) + noise, GOAL_MARGIN, 1.0 - GOAL_MARGIN)
    return (round(float(c[0]), 4), round(float(c[1]), 4), round(float(c[2]), 4), 1.0)
