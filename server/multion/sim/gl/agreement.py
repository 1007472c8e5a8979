"""How closely two renderers' images agree: the measure of ``gl`` against TinyRenderer
(``tests/sim/test_gl_renderer.py``, ``multion bench --only sim``)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

DEPTH_TOLERANCE_M = 0.01


class Image(Protocol):
    @property
    def rgb(self) -> np.ndarray: ...
    @property
    def depth(self) -> np.ndarray: ...
    @property
    def segmentation(self) -> np.ndarray | None: ...


@dataclass(frozen=True)
class Agreement:
    depth: float
    """Share of pixels whose depths (metres) differ by at most ``DEPTH_TOLERANCE_M``."""
    segmentation: float
    """Share of pixels with the same body id."""
    rgb_mean: float
    """Mean absolute difference per channel, 0-255 levels."""
    rgb_p99: float
    """99th percentile of the absolute differences per channel."""
    pixels: int


def agreement(
    reference: Sequence[Image], other: Sequence[Image], depth_scale: float = 1.0
) -> Agreement:
    """Pixel agreement over paired images; ``depth_scale`` turns their depth into metres."""
    depth = np.concatenate(
        [
            np.abs(a.depth - b.depth).ravel() * depth_scale
            for a, b in zip(reference, other, strict=True)
        ]
    )
    same = np.concatenate(
        [_segmentation(a) == _segmentation(b) for a, b in zip(reference, other, strict=True)]
    )
    rgb = np.concatenate(
        [
            np.abs(a.rgb.astype(np.int16) - b.rgb.astype(np.int16)).ravel()
            for a, b in zip(reference, other, strict=True)
        ]
    )
    return Agreement(
        depth=float((depth <= DEPTH_TOLERANCE_M).mean()),
        segmentation=float(same.mean()),
        rgb_mean=float(rgb.mean()),
        rgb_p99=float(np.percentile(rgb, 99)),
        pixels=int(depth.size),
    )


def _segmentation(image: Image) -> np.ndarray:
    if image.segmentation is None:
        raise ValueError("agreement needs images rendered with segmentation")
    return image.segmentation.ravel()
