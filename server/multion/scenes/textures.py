"""Procedural textures for floors and walls: wood planks, tiles, carpet, wallpaper, plaster.

A texture is a grey pattern (values in about [0.6, 1]) that the renderer multiplies with the
box's colour, so a room keeps its colour and gains a surface. PyBullet stretches one copy of a
texture over every face of a box, so the image is made for the size of the face it will cover:
``size_u`` × ``size_v`` metres, with planks, tiles or stripes of their real size. Images are a
pure function of (pattern, size), written once to a cache folder and shared by every process.
"""

from __future__ import annotations

import tempfile
import zlib
from pathlib import Path

import numpy as np

from multion.common.files import replacing

PATTERNS = ("planks", "tiles", "small_tiles", "carpet", "stripes", "plaster")
PIXELS_PER_METRE = 40
MAX_PIXELS = 512
SIZE_STEP = 0.25  # face sizes are rounded to this, so houses share images


def _rng(pattern: str, u: float, v: float) -> np.random.Generator:
    return np.random.default_rng(zlib.crc32(f"{pattern}:{u:.2f}:{v:.2f}".encode()))


def texture_image(pattern: str, size_u: float, size_v: float) -> np.ndarray:
    """The (H, W, 3) uint8 image of ``pattern`` for a ``size_u`` × ``size_v`` m face."""
    if pattern not in PATTERNS:
        raise ValueError(f"unknown texture {pattern!r}; known: {', '.join(PATTERNS)}")
    u, v = (max(SIZE_STEP, round(s / SIZE_STEP) * SIZE_STEP) for s in (size_u, size_v))
    w = int(min(MAX_PIXELS, max(16, u * PIXELS_PER_METRE)))
    h = int(min(MAX_PIXELS, max(16, v * PIXELS_PER_METRE)))
    rng = _rng(pattern, u, v)
    # metres at each pixel centre
    x = (np.arange(w) + 0.5) * u / w
    y = (np.arange(h) + 0.5) * v / h
    xx, yy = np.meshgrid(x, y)
    grain = rng.uniform(-1, 1, size=(h, w))
    if pattern == "planks":  # boards 0.18 m wide along y, joints staggered every ~1.2 m
        board = np.floor(yy / 0.18).astype(int)
        offset = _hash(board, 7) * 1.2
        piece = np.floor((xx + offset) / 1.2).astype(int)
        tone = 0.8 + 0.2 * _hash(board * 131 + piece, 3)
        seam = (np.mod(yy, 0.18) < 0.012) | (np.mod(xx + offset, 1.2) < 0.012)
        value = np.where(seam, 0.62, tone + 0.03 * grain + 0.03 * np.sin(xx * 40 + board))
    elif pattern in ("tiles", "small_tiles"):
        side = 0.4 if pattern == "tiles" else 0.2
        grout = (np.mod(xx, side) < 0.012) | (np.mod(yy, side) < 0.012)
        tile = np.floor(xx / side).astype(int) * 977 + np.floor(yy / side).astype(int)
        value = np.where(grout, 0.7, 0.93 + 0.05 * _hash(tile, 5) + 0.01 * grain)
    elif pattern == "carpet":
        value = 0.86 + 0.08 * grain
    elif pattern == "stripes":  # wallpaper: 0.15 m stripes along u
        value = np.where(np.mod(xx, 0.3) < 0.15, 1.0, 0.86) + 0.01 * grain
    else:  # plaster: faint blotches
        coarse = rng.uniform(-1, 1, size=(max(2, h // 8), max(2, w // 8)))
        blotches = np.kron(coarse, np.ones((8, 8)))[:h, :w]
        pad = ((0, h - blotches.shape[0]), (0, w - blotches.shape[1]))
        value = 0.93 + 0.04 * np.pad(blotches, pad, mode="edge") + 0.01 * grain
    grey = (np.clip(value, 0.0, 1.0) * 255).astype(np.uint8)
    return np.repeat(grey[:, :, None], 3, axis=2)


def _hash(index: np.ndarray, salt: int) -> np.ndarray:
    """A repeatable pseudo-random value in [0, 1) per integer index."""
    k = (np.asarray(index, dtype=np.int64) * 2654435761 + salt * 40503) % 4294967296
    return ((k * 2246822519) % 4294967296) / 4294967296.0


def texture_file(pattern: str, size_u: float, size_v: float, folder: Path | None = None) -> Path:
    """A PNG of :func:`texture_image` in the cache folder (written once, atomically)."""
    from PIL import Image

    u, v = (max(SIZE_STEP, round(s / SIZE_STEP) * SIZE_STEP) for s in (size_u, size_v))
    folder = folder or Path(tempfile.gettempdir()) / "multion-textures"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{pattern}-{u:.2f}x{v:.2f}.png"
    if not path.is_file():
        with replacing(path) as temporary:
            Image.fromarray(texture_image(pattern, u, v)).save(temporary)
    return path
