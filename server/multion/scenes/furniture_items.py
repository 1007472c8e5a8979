"""The furniture catalogue: pieces made of boxes, and which pieces each room type gets.

Each piece is an :class:`Item` built in its own frame: ``u`` runs along the wall it stands
against, ``v`` points away from that wall into the room, ``z`` is up. Where an item goes is
decided in :mod:`multion.scenes.furniture`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from multion.scenes.layout import Rgba
from multion.scenes.palette import (
    BRIGHT,
    BRIGHT_COLOURS,
    FABRICS,
    MATERIALS,
    WOODS,
    bright,
    varied,
)

Rect = tuple[float, float, float, float]  # (x0, y0, x1, y1)
AGENT_HEIGHT = 1.5  # parts starting higher than this do not block the agent


@dataclass(frozen=True)
class Part:
    """One box of an item, as low and high corners ``(u, v, z)`` in the item's frame."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    rgba: Rgba


@dataclass(frozen=True)
class Item:
    """A piece of furniture: a ``width`` × ``depth`` footprint in its frame and its parts."""

    name: str
    width: float
    depth: float
    parts: tuple[Part, ...]
    centre: bool = False  # stands in the middle of the room instead of against a wall
    anywhere: bool = False  # clutter: anywhere in the room, turned by a multiple of 90°


def _p(u0: float, v0: float, z0: float, u1: float, v1: float, z1: float, rgba: Rgba) -> Part:
    return Part((u0, v0, z0), (u1, v1, z1), rgba)


def _legs(u0: float, v0: float, u1: float, v1: float, top: float, rgba: Rgba) -> list[Part]:
    s = 0.05  # leg thickness
    return [_p(u, v, 0.0, u + s, v + s, top, rgba) for u in (u0, u1 - s) for v in (v0, v1 - s)]


def _table(u0: float, v0: float, u1: float, v1: float, height: float, rgba: Rgba) -> list[Part]:
    return [_p(u0, v0, height - 0.04, u1, v1, height, rgba), *_legs(u0, v0, u1, v1, height, rgba)]


def _chair(u0: float, v0: float, back_at_low_v: bool, wood: Rgba, seat: Rgba) -> list[Part]:
    """A 0.45 m chair whose lower corner is ``(u0, v0)``; the back is on the low- or high-v side."""
    u1, v1 = u0 + 0.45, v0 + 0.45
    back_v = (v0, v0 + 0.05) if back_at_low_v else (v1 - 0.05, v1)
    return [
        *_legs(u0, v0, u1, v1, 0.43, wood),
        _p(u0, v0, 0.42, u1, v1, 0.47, seat),
        _p(u0, back_v[0], 0.46, u1, back_v[1], 0.92, wood),
    ]


def _mat(rng: np.random.Generator, *names: str) -> Rgba:
    name = names[int(rng.integers(len(names)))]
    if name in BRIGHT_COLOURS:
        return bright(BRIGHT_COLOURS[name], rng)
    return varied(MATERIALS[name], rng)


def _snap(x: float) -> float:
    return round(x * 20) / 20  # 5 cm steps keep sizes readable


# ----------------------------------------------------------------------------- item builders


def bed_set(rng: np.random.Generator) -> Item:
    bw, bl = float(rng.choice([0.9, 1.4, 1.6, 1.8])), 2.05
    stands = int(rng.choice([0, 1, 2], p=[0.2, 0.3, 0.5]))
    wood, linen = _mat(rng, "wood_light", "wood_mid"), _mat(rng, "linen")
    blanket = _mat(rng, *FABRICS, *BRIGHT)
    b0 = 0.5 if stands else 0.0
    b1 = b0 + bw
    parts = [
        _p(b0, 0, 0, b1, bl, 0.3, wood),
        _p(b0 + 0.03, 0.08, 0.29, b1 - 0.03, bl - 0.03, 0.5, linen),
        _p(b0, 0, 0, b1, 0.06, 1.0, wood),
        _p(b0 + 0.12, 0.12, 0.49, b1 - 0.12, 0.45, 0.62, linen),
        _p(b0 + 0.01, 0.8, 0.48, b1 - 0.01, bl - 0.01, 0.54, blanket),
    ]
    for s0 in [0.0, b1 + 0.05][:stands]:
        parts.append(_p(s0, 0, 0, s0 + 0.45, 0.4, 0.55, wood))
    return Item("bed", b1 + (0.5 if stands == 2 else 0.0), bl, tuple(parts))


def wardrobe(rng: np.random.Generator) -> Item:
    w, d, h = _snap(rng.uniform(1.0, 1.8)), 0.6, 2.05
    wood, metal = _mat(rng, "wood_light", "wood_mid", "wood_dark"), _mat(rng, "metal")
    seam = _mat(rng, "wood_dark")
    parts = [
        _p(0, 0, 0, w, d - 0.01, h, wood),
        _p(w / 2 - 0.005, d - 0.02, 0.05, w / 2 + 0.005, d, h - 0.05, seam),
        _p(w / 2 - 0.1, d - 0.02, 1.0, w / 2 - 0.07, d, 1.3, metal),
        _p(w / 2 + 0.07, d - 0.02, 1.0, w / 2 + 0.1, d, 1.3, metal),
    ]
    return Item("wardrobe", w, d, tuple(parts))


def bookshelf(rng: np.random.Generator) -> Item:
    w, d, h = _snap(rng.uniform(0.8, 1.2)), 0.35, _snap(rng.uniform(1.8, 2.1))
    wood = _mat(rng, "wood_light", "wood_mid", "wood_dark")
    parts = [
        _p(0, 0, 0, w, 0.02, h, wood),
        _p(0, 0, 0, 0.03, d, h, wood),
        _p(w - 0.03, 0, 0, w, d, h, wood),
        _p(0.02, 0, h - 0.03, w - 0.02, d, h, wood),
        _p(0.02, 0, 0, w - 0.02, d, 0.08, wood),
    ]
    levels = np.linspace(0.08, h - 0.03, 5)
    for z in levels[1:-1]:
        parts.append(_p(0.02, 0.01, z - 0.025, w - 0.02, d, z, wood))
    for z in levels[:-1]:  # a row of books on every shelf
        bw, bh = _snap(rng.uniform(0.2, w - 0.2)), float(rng.uniform(0.18, 0.28))
        u0 = float(rng.uniform(0.04, w - 0.04 - bw))
        parts.append(_p(u0, 0.04, z, u0 + bw, 0.26, z + bh, _mat(rng, *FABRICS, *BRIGHT)))
    return Item("bookshelf", w, d, tuple(parts))


def sofa_set(rng: np.random.Generator) -> Item:
    sw, sd = _snap(rng.uniform(1.8, 2.4)), 0.9
    fabric, wood = _mat(rng, *FABRICS, *BRIGHT), _mat(rng, "wood_light", "wood_mid", "wood_dark")
    parts = [
        _p(0.02, 0.02, 0, sw - 0.02, sd - 0.02, 0.11, wood),
        _p(0.14, 0.05, 0.1, sw - 0.14, sd, 0.45, fabric),
        _p(0, 0, 0.1, sw, 0.22, 0.85, fabric),
        _p(0, 0, 0.1, 0.15, sd, 0.62, fabric),
        _p(sw - 0.15, 0, 0.1, sw, sd, 0.62, fabric),
    ]
    depth = sd
    if rng.random() < 0.7:  # coffee table in front of the sofa
        tw = min(sw - 0.4, _snap(rng.uniform(0.9, 1.2)))
        u0, v0 = (sw - tw) / 2, sd + 0.4
        parts += _table(u0, v0, u0 + tw, v0 + 0.55, 0.42, wood)
        depth = v0 + 0.55
    return Item("sofa", sw, depth, tuple(parts))


def armchair(rng: np.random.Generator) -> Item:
    fabric, wood = _mat(rng, *FABRICS, *BRIGHT), _mat(rng, "wood_mid", "wood_dark")
    parts = (
        _p(0.02, 0.02, 0, 0.83, 0.83, 0.1, wood),
        _p(0.13, 0.05, 0.09, 0.72, 0.85, 0.44, fabric),
        _p(0, 0, 0.09, 0.85, 0.2, 0.85, fabric),
        _p(0, 0, 0.09, 0.14, 0.85, 0.6, fabric),
        _p(0.71, 0, 0.09, 0.85, 0.85, 0.6, fabric),
    )
    return Item("armchair", 0.85, 0.85, parts)


def tv_stand(rng: np.random.Generator) -> Item:
    w = _snap(rng.uniform(1.3, 1.8))
    tw = min(w - 0.2, _snap(rng.uniform(0.9, 1.3)))
    wood, screen = _mat(rng, "wood_mid", "wood_dark", "linen"), _mat(rng, "screen")
    u0 = (w - tw) / 2
    parts = (
        _p(0, 0, 0, w, 0.42, 0.5, wood),
        _p(w / 2 - 0.1, 0.12, 0.49, w / 2 + 0.1, 0.28, 0.58, screen),
        _p(u0, 0.15, 0.57, u0 + tw, 0.2, 0.57 + 0.56 * tw, screen),
    )
    return Item("tv", w, 0.42, parts)


def kitchen_counter(rng: np.random.Generator) -> Item:
    w = _snap(rng.uniform(1.8, 3.0))
    body, top = _mat(rng, "wood_light", "linen", "wood_mid"), _mat(rng, "stone", "ceramic")
    metal, hob = _mat(rng, "metal"), _mat(rng, "screen")
    sink0 = 0.2 + float(rng.random()) * max(w - 1.8, 0.0)
    parts = (
        _p(0, 0, 0.08, w, 0.58, 0.86, body),
        _p(0.03, 0, 0, w - 0.03, 0.52, 0.09, top),  # recessed plinth
        _p(0, 0, 0.85, w, 0.62, 0.9, top),
        _p(sink0, 0.1, 0.89, sink0 + 0.5, 0.5, 0.905, metal),
        _p(w - 0.8, 0.1, 0.89, w - 0.2, 0.5, 0.91, hob),
        _p(0, 0, 1.5, w, 0.35, 2.2, body),
    )
    return Item("counter", w, 0.62, parts)


def fridge(rng: np.random.Generator) -> Item:
    metal, handle = _mat(rng, "metal", "ceramic", "paint_white", "paint_black"), _mat(rng, "stone")
    parts = (_p(0, 0, 0, 0.7, 0.68, 1.85, metal), _p(0.6, 0.67, 0.9, 0.63, 0.72, 1.5, handle))
    return Item("fridge", 0.7, 0.72, parts)


def dining_set(rng: np.random.Generator, small: bool = False) -> Item:
    tw = _snap(rng.uniform(0.8, 1.0) if small else rng.uniform(1.4, 1.8))
    td = 0.8 if small else 0.9
    wood, seat = _mat(rng, "wood_light", "wood_mid", "wood_dark"), _mat(rng, *FABRICS)
    v_table = 0.55  # chairs take 0.55 m on both long sides
    parts = _table(0, v_table, tw, v_table + td, 0.76, wood)
    per_side = 1 if small else (3 if tw >= 1.7 else 2)
    for k in range(per_side):
        u0 = (k + 0.5) * tw / per_side - 0.225
        parts += _chair(u0, 0.02, True, wood, seat)
        parts += _chair(u0, v_table + td + 0.08, False, wood, seat)
    return Item("dining_table", tw, v_table * 2 + td, tuple(parts), centre=True)


def desk_set(rng: np.random.Generator) -> Item:
    dw, dd = _snap(rng.uniform(1.1, 1.5)), 0.65
    wood, seat = _mat(rng, "wood_light", "wood_mid"), _mat(rng, *FABRICS)
    screen = _mat(rng, "screen")
    parts = [
        _p(0, 0, 0.72, dw, dd, 0.76, wood),
        _p(0, 0, 0, 0.04, dd, 0.73, wood),
        _p(dw - 0.04, 0, 0, dw, dd, 0.73, wood),
        _p(dw / 2 - 0.25, 0.1, 0.8, dw / 2 + 0.25, 0.13, 1.12, screen),
        _p(dw / 2 - 0.05, 0.08, 0.75, dw / 2 + 0.05, 0.2, 0.81, screen),
        *_chair(dw / 2 - 0.225, 0.55, False, wood, seat),
    ]
    return Item("desk", dw, 1.0, tuple(parts))


def bathtub(rng: np.random.Generator) -> Item:
    bw, d, r = _snap(rng.uniform(1.6, 1.75)), 0.75, 0.08
    ceramic = _mat(rng, "ceramic")
    parts = (
        _p(0, 0, 0, bw, d, 0.35, ceramic),
        _p(0, 0, 0.34, bw, r, 0.55, ceramic),
        _p(0, d - r, 0.34, bw, d, 0.55, ceramic),
        _p(0, r - 0.01, 0.34, r, d - r + 0.01, 0.55, ceramic),
        _p(bw - r, r - 0.01, 0.34, bw, d - r + 0.01, 0.55, ceramic),
    )
    return Item("bathtub", bw, d, parts)


def toilet(rng: np.random.Generator) -> Item:
    ceramic = _mat(rng, "ceramic")
    parts = (
        _p(0, 0, 0, 0.42, 0.2, 0.8, ceramic),
        _p(0.03, 0.18, 0, 0.39, 0.66, 0.41, ceramic),
        _p(0.02, 0.19, 0.4, 0.4, 0.68, 0.44, ceramic),
    )
    return Item("toilet", 0.42, 0.68, parts)


def sink_cabinet(rng: np.random.Generator) -> Item:
    w = _snap(rng.uniform(0.6, 0.9))
    wood, ceramic, metal = (
        _mat(rng, "wood_light", "wood_mid"),
        _mat(rng, "ceramic"),
        _mat(rng, "metal"),
    )
    parts = (
        _p(0, 0, 0, w, 0.46, 0.8, wood),
        _p(0, 0, 0.79, w, 0.48, 0.86, ceramic),
        _p(w / 2 - 0.02, 0.03, 0.85, w / 2 + 0.02, 0.12, 0.98, metal),
        _p(0.05, 0, 1.15, w - 0.05, 0.02, 1.75, metal),
    )
    return Item("sink", w, 0.48, parts)


def cabinet(rng: np.random.Generator, name: str = "sideboard", lo: float = 1.2) -> Item:
    """A low cabinet on legs: sideboard, hallway console, filing cabinet …"""
    w, d = _snap(rng.uniform(lo, lo + 0.5)), 0.45
    wood, dark = _mat(rng, "wood_light", "wood_mid", "wood_dark", "metal"), _mat(rng, "wood_dark")
    parts = (
        _p(0, 0, 0.12, w, d - 0.01, 0.85, wood),
        *_legs(0.02, 0.02, w - 0.02, d - 0.03, 0.13, dark),
        _p(0.05, d - 0.02, 0.5, w - 0.05, d, 0.51, dark),
    )
    return Item(name, w, d, parts)


def plant(rng: np.random.Generator) -> Item:
    pot = _mat(rng, "wood_dark", "stone", "fabric_rust", "paint_red", "paint_white", "paint_blue")
    leaves = _mat(rng, "foliage", "foliage", "paint_green")
    h = float(rng.uniform(0.8, 1.3))
    parts = (_p(0.05, 0.05, 0, 0.35, 0.35, 0.35, pot), _p(0, 0, 0.33, 0.4, 0.4, h, leaves))
    return Item("plant", 0.4, 0.4, parts)


def kitchen_island(rng: np.random.Generator) -> Item:
    w, d = _snap(rng.uniform(1.2, 2.0)), _snap(rng.uniform(0.8, 1.0))
    body, top = (
        _mat(rng, "wood_light", "linen", "wood_mid", "paint_red", "paint_blue"),
        _mat(rng, "stone", "ceramic"),
    )
    seat = _mat(rng, "metal", "wood_dark", "paint_white", "paint_yellow")
    parts = [_p(0.05, 0.45, 0, w - 0.05, 0.45 + d - 0.05, 0.88, body),
             _p(0, 0.4, 0.88, w, 0.45 + d, 0.92, top)]  # fmt: skip
    stools = max(1, int(w // 0.6))
    for k in range(stools):
        u = (k + 0.5) * w / stools
        parts += [_p(u - 0.17, 0.0, 0, u + 0.17, 0.34, 0.65, seat)]
    return Item("island", w, 0.45 + d, tuple(parts), anywhere=True)


def coffee_table(rng: np.random.Generator) -> Item:
    w, d = _snap(rng.uniform(0.8, 1.2)), _snap(rng.uniform(0.5, 0.7))
    return Item("coffee_table", w, d, tuple(_table(0, 0, w, d, 0.42, _mat(rng, *WOODS, "glass"))),
                anywhere=True)  # fmt: skip


def ottoman(rng: np.random.Generator) -> Item:
    s = _snap(rng.uniform(0.45, 0.7))
    return Item("ottoman", s, s, (_p(0, 0, 0, s, s, 0.42, _mat(rng, *FABRICS, *BRIGHT)),),
                anywhere=True)  # fmt: skip


def floor_lamp(rng: np.random.Generator) -> Item:
    base, pole = _mat(rng, "metal", "screen"), _mat(rng, "metal")
    shade = _mat(rng, "linen", "paint_white", "paint_yellow", "fabric_sand")
    parts = (_p(0, 0, 0, 0.32, 0.32, 0.04, base), _p(0.14, 0.14, 0.04, 0.18, 0.18, 1.45, pole),
             _p(0.03, 0.03, 1.4, 0.29, 0.29, 1.7, shade))  # fmt: skip
    return Item("floor_lamp", 0.32, 0.32, parts, anywhere=True)


def side_table(rng: np.random.Generator) -> Item:
    s = _snap(rng.uniform(0.4, 0.55))
    return Item("side_table", s, s, tuple(_table(0, 0, s, s, 0.55, _mat(rng, *WOODS, *BRIGHT))),
                anywhere=True)  # fmt: skip


def boxes_pile(rng: np.random.Generator) -> Item:
    """Moving boxes, a laundry basket, toys …: one to three small boxes."""
    parts, u = [], 0.0
    for _ in range(int(rng.integers(1, 4))):
        w, d, h = (float(rng.uniform(0.3, 0.6)) for _ in range(3))
        colour = _mat(rng, "cardboard", "cardboard", *BRIGHT, *FABRICS)
        parts.append(_p(u, 0, 0, u + w, d, h, colour))
        u += w + 0.02
    depth = max(p.hi[1] for p in parts)
    return Item("boxes", u - 0.02, depth, tuple(parts), anywhere=True)


def rug(rng: np.random.Generator) -> Item:
    """A thin rug: it does not block the agent, it is there to be looked at (and mistaken)."""
    w, d = _snap(rng.uniform(1.4, 2.8)), _snap(rng.uniform(1.0, 2.0))
    return Item("rug", w, d, (_p(0, 0, 0, w, d, 0.012, _mat(rng, *BRIGHT, *FABRICS)),),
                anywhere=True)  # fmt: skip


def dining_anywhere(rng: np.random.Generator) -> Item:
    item = dining_set(rng, small=bool(rng.random() < 0.5))
    return Item(item.name, item.width, item.depth, item.parts, anywhere=True)


def plant_anywhere(rng: np.random.Generator) -> Item:
    item = plant(rng)
    return Item(item.name, item.width, item.depth, item.parts, anywhere=True)


def armchair_anywhere(rng: np.random.Generator) -> Item:
    item = armchair(rng)
    return Item(item.name, item.width, item.depth, item.parts, anywhere=True)


Builder = Callable[[np.random.Generator], Item]

# Per room type: (builder, probability of trying it) in the order they are placed.
ROOM_FURNITURE: dict[str, list[tuple[Builder, float]]] = {
    "living_room": [(sofa_set, 1.0), (tv_stand, 0.9), (bookshelf, 0.6), (armchair, 0.5),
                    (plant, 0.5)],
    "kitchen": [(kitchen_counter, 1.0), (fridge, 0.9), (kitchen_counter, 0.5),
                (lambda rng: dining_set(rng, small=True), 0.4)],
    "bedroom": [(bed_set, 1.0), (wardrobe, 0.9), (desk_set, 0.3), (plant, 0.3)],
    "bathroom": [(bathtub, 0.9), (toilet, 1.0), (sink_cabinet, 1.0)],
    "dining_room": [(dining_set, 1.0), (cabinet, 0.8), (bookshelf, 0.3), (plant, 0.4)],
    "office": [(desk_set, 1.0), (bookshelf, 0.9), (lambda rng: cabinet(rng, "files", 0.5), 0.5),
               (armchair, 0.3)],
    "hallway": [(lambda rng: cabinet(rng, "console", 0.8), 0.6), (plant, 0.4)],
}  # fmt: skip

# Clutter in the middle of rooms, per room type: tried ``clutter`` rounds after the furniture
# along the walls (each round tries every entry with its probability).
ROOM_CLUTTER: dict[str, list[tuple[Builder, float]]] = {
    "living_room": [(rug, 0.5), (coffee_table, 0.7), (armchair_anywhere, 0.4), (ottoman, 0.5),
                    (floor_lamp, 0.4), (side_table, 0.4), (plant_anywhere, 0.4),
                    (dining_anywhere, 0.25)],
    "kitchen": [(kitchen_island, 0.5), (dining_anywhere, 0.3), (boxes_pile, 0.3),
                (plant_anywhere, 0.2)],
    "bedroom": [(rug, 0.4), (ottoman, 0.4), (boxes_pile, 0.5), (side_table, 0.3),
                (floor_lamp, 0.3), (armchair_anywhere, 0.3)],
    "bathroom": [(boxes_pile, 0.5), (plant_anywhere, 0.3)],
    "dining_room": [(rug, 0.3), (side_table, 0.4), (plant_anywhere, 0.5), (boxes_pile, 0.3),
                    (floor_lamp, 0.3)],
    "office": [(boxes_pile, 0.6), (armchair_anywhere, 0.4), (plant_anywhere, 0.4),
               (side_table, 0.4), (floor_lamp, 0.3)],
    "hallway": [(plant_anywhere, 0.4), (boxes_pile, 0.4), (side_table, 0.3), (rug, 0.3)],
}  # fmt: skip
