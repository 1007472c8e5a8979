"""The reference code's ``semMap``, cell for cell, for habitat-style agents.

The reference (saimwani/multiON at 2ba4d25, ``habitat/core/env.py``) builds its oracle map on a
world-aligned grid whose rows run along -x and columns along +z (``conv_grid``, l. 214-233); it
cuts an 80 × 80 patch around the agent's cell, turns it with ``ndimage.rotate(patch,
-heading° + 90, order=0, reshape=False)`` and keeps the centre 50 × 50 (l. 291-293 on reset,
347-349 on step). In that crop ahead is *down*, the agent's left is to the *right*, and the agent's
cell moves between (24|25, 24|25) with the heading. This project's ``oracle_map`` crop (the
``project`` convention, :mod:`multion.task.maps`) has ahead up, left to the left, and the agent
fixed in cell (25, 25): another picture of the same map.

Why the server builds it: a crop resampled at an angle that is not a multiple of 90° has already
dropped some map cells and doubled others, and the reference resamples the *world-aligned*
patch at the agent's *absolute* heading, while a client sees only its heading relative to the
start (``compass``). So the reference's crop cannot be rebuilt from this project's crop, not even
with the compass. A run asks instead for ``maps.convention = "reference"``
(:data:`REFERENCE_MAPS`), and the server cuts its crops the reference's way from its global map
and the agent's true pose, in numpy arithmetic equal to ``ndimage.rotate``'s (order 0, nearest
cell). The client is left with what only it knows: the goal set, hence the ids to give objects.

Values in the ``reference`` convention, as the reference writes them: ``oracle_map`` channel 0 is
the occupancy (0 outside the scene, 1 free, 2 occupied), channel 1 the object category + 1 (l. 278
``objIndexOffset = 1``; 0 for no object); ``oracle_ego_map`` is 0 in both channels where the agent
has not looked and the map + 1 where it has (``mapCache[x] += 1``, l. 137-139): occupancy + 1, and
1 for no object or category + 2 (``objIndexOffset = 2``). The server numbers categories as this
project does; :func:`reference_sem_map` renumbers them in the reference's colour order. The
reference's map has a third channel its policy never reads (``policy.py`` l. 463-466 read
channels 0 and 1); here there are two.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

PROJECT_CONVENTION = "project"
REFERENCE_CONVENTION = "reference"
MAP_CONVENTIONS = (PROJECT_CONVENTION, REFERENCE_CONVENTION)
"""The values of ``maps.convention``: how the server lays out its oracle-map crops."""
REFERENCE_MAPS = {"convention": REFERENCE_CONVENTION}
"""The ``maps`` options of a run whose oracle maps are the reference's ``semMap``."""
OBJECT_OFFSETS = {"oracle_map": 1, "oracle_ego_map": 2}
"""What the reference adds to an object's category (``objIndexOffset``, l. 278); in the ego map,
``offset - 1`` marks a cell seen without an object."""


def reference_sem_map(crop: np.ndarray, sensor: str, order: Sequence[int]) -> np.ndarray:
    """``semMap`` from a ``reference``-convention crop of ``sensor`` (``oracle_map`` or
    ``oracle_ego_map``): object categories renumbered by ``order`` (category id here -> the
    reference's index), everything else as it came."""
    if sensor not in OBJECT_OFFSETS:
        raise ValueError(f"sensor must be one of {sorted(OBJECT_OFFSETS)}, got {sensor!r}")
    offset = OBJECT_OFFSETS[sensor]
    out = np.array(crop, copy=True)
    objects = out[..., 1]
    marked = objects >= offset
    categories = objects[marked].astype(np.int64) - offset
    if categories.size and int(categories.max()) >= len(order):
        raise ValueError(
            f"{sensor} holds object value {int(categories.max()) + offset}; with {len(order)} "
            f"categories the values are 0..{len(order) - 1 + offset}"
        )
    lookup = np.asarray(order, dtype=np.int64)
    objects[marked] = (lookup[categories] + offset).astype(out.dtype)
    return out
