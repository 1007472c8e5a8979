"""Geometry of the learned maps, in torch (batched, differentiable w.r.t. map contents).

Frames and conventions (those of the environment and of ``multion.task.maps.OracleMap``):

Every length comes from :class:`MapGeometry`, read from the env config (cell size, camera field
of view and depth range, crop size); numbers below are for the default 0.8 m cells.

* The **global map** is a (…, G, G) grid of ``cell_size`` cells in the episode's start frame,
  centred on the start position and drawn "start heading up": row ``r``, column ``q`` is the
  cell whose centre is ``x = (c - r)·s`` ahead and ``y = (c - q)·s`` to the left of the start,
  ``c = G // 2``. At compass 0 the global map and the egocentric crop are drawn alike.
* ``gps`` (B, 2) is (ahead, left) in metres in the start frame; ``compass`` (B, 1) is the
  heading relative to the start, counter-clockwise positive (a left turn increases it).
* An **egocentric crop** (S × S) is rotated so that ahead is up: row 0 ahead, column 0
  left, the agent in cell ``(S // 2, S // 2)``: the centre cell for an odd S; for an even S
  (the default 50) S / 2 cells ahead and to the left, one fewer behind and to the right, as
  in the oracle maps and the reference's ``patch[40-25:40+25]``.
* The **egocentric projection grid** of ProjNeuralMap/EgoMap is ``EGO_ROWS`` × ``EGO_COLS``
  (7 × 13 cells) with the agent at the centre of the bottom-middle cell: it is the part of a
  13 × 13 egocentric crop ahead of the agent. Row ``EGO_ROWS - 1 - k`` holds points
  ``(k ± 0.5)·0.8 m`` ahead, column ``EGO_COLS // 2 + j`` points ``(j ± 0.5)·0.8 m`` to the right
  (lower columns: left). It spans 5.2 m ahead and ±5.2 m sideways. (The supplement says
  5.6 m ahead, the agent at the mid-bottom; centring the agent in its cell aligns the grid with
  the global map's cells at the start pose; points seen farther than the grid reaches, up to
  the depth sensor's 10 m, are dropped: :func:`project_egocentric`.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import torch
import torch.nn.functional as F
from torch import Tensor

from multion.config.codec import env_config_from_dict
from multion.config.task import EnvConfig

GLOBAL_SIZE = 63
"""Side of the learned global map, cells: 50.4 m at 0.8 m, ±25 m around the start (the paper's
map is 300 × 300 cells; our procedural houses are < 25 m across, so this is never left). A
model choice, not an env setting."""
FAR_FRACTION = 0.999
"""Depths at or above this fraction of the depth range were clipped at the far limit: no
surface seen there."""
EGO_ROWS, EGO_COLS = 7, 13
"""Egocentric projection grid (supplement: 7 × 13 cells, 5.6 m ahead and to both sides)."""


@dataclass(frozen=True)
class MapGeometry:
    """Everything the learned maps must agree on with the environment, read from its config
    (:meth:`from_env_config`; a checkpoint stores the config it was trained with)."""

    cell_size: float
    """Map cell side, metres (``maps.cell_size``; paper 0.8)."""
    crop_size: int
    """Side of the egocentric crop read by the map CNN, cells (``maps.ego_size``)."""
    hfov_deg: float
    """Camera horizontal field of view (``camera.hfov_deg``)."""
    min_depth: float
    max_depth: float
    """Depth range, metres (``camera.min_depth`` / ``camera.max_depth``)."""
    normalized_depth: bool
    """Depth observations in [0, 1] over the range (``camera.normalize_depth``), else metres."""
    global_size: int = GLOBAL_SIZE

    @classmethod
    def from_env_config(cls, config: Any) -> MapGeometry:
        """From a :class:`multion.config.task.EnvConfig` or its nested-dict form."""
        if isinstance(config, dict):
            config = env_config_from_dict(config)
        camera, maps = config.camera, config.maps
        return cls(
            cell_size=maps.cell_size,
            crop_size=maps.ego_size,
            hfov_deg=camera.hfov_deg,
            min_depth=camera.min_depth,
            max_depth=camera.max_depth,
            normalized_depth=camera.normalize_depth,
        )

    def depth_metres(self, depth: Tensor) -> Tensor:
        """A depth observation → planar depth in metres."""
        if not self.normalized_depth:
            return depth
        return self.min_depth + depth * (self.max_depth - self.min_depth)

    def far(self, depth: Tensor) -> Tensor:
        """True where a depth observation was clipped at the far limit."""
        metres = self.depth_metres(depth)
        return metres >= self.min_depth + FAR_FRACTION * (self.max_depth - self.min_depth)


def default_geometry() -> MapGeometry:
    """The geometry of the default environment config (for tests and quick experiments)."""
    return MapGeometry.from_env_config(EnvConfig())


def _unit(compass: Tensor) -> tuple[Tensor, Tensor]:
    yaw = compass.reshape(-1)
    return torch.cos(yaw), torch.sin(yaw)


def world_cell(gps: Tensor, size: int, cell_size: float) -> tuple[Tensor, Tensor, Tensor]:
    """The global-map cell (row, col) holding each position of ``gps`` (B, 2), and whether it
    lies inside the map."""
    centre = size // 2
    row = torch.floor(centre + 0.5 - gps[:, 0] / cell_size).long()
    col = torch.floor(centre + 0.5 - gps[:, 1] / cell_size).long()
    inside = (row >= 0) & (row < size) & (col >= 0) & (col < size)
    return row, col, inside


def crop_offsets(
    crop: int, cell_size: float, device: torch.device | None = None
) -> tuple[Tensor, Tensor]:
    """(ahead, left) metres of the centres of an egocentric crop's cells, each (S, S)."""
    half = crop // 2
    index = torch.arange(crop, dtype=torch.float32, device=device)
    rows, cols = torch.meshgrid(index, index, indexing="ij")
    return (half - rows) * cell_size, (half - cols) * cell_size


def egocentric_crop(
    global_map: Tensor,
    gps: Tensor,
    compass: Tensor,
    crop: int,
    cell_size: float,
    mode: str = "nearest",
) -> Tensor:
    """The S × S egocentric crop (B, C, S, S) of ``global_map`` (B, C, G, G) around each agent,
    rotated so that ahead is up. Cells outside the global map read as 0 (empty)."""
    size = global_map.shape[-1]
    ahead, left = crop_offsets(crop, cell_size, global_map.device)
    cos, sin = (v.view(-1, 1, 1) for v in _unit(compass))
    x = gps[:, 0].view(-1, 1, 1) + ahead * cos - left * sin
    y = gps[:, 1].view(-1, 1, 1) + ahead * sin + left * cos
    centre = size // 2
    row = centre - x / cell_size
    col = centre - y / cell_size
    grid = torch.stack([col, row], dim=-1) * (2.0 / (size - 1)) - 1.0
    return F.grid_sample(
        global_map, grid.to(global_map.dtype), mode=mode, padding_mode="zeros", align_corners=True
    )


def relative_cell_positions(
    gps: Tensor, compass: Tensor, size: int, cell_size: float, pool: int = 1
) -> Tensor:
    """(ahead, left) metres of every global cell's centre relative to each agent: (B, G·G, 2).

    With ``pool`` > 1, of the centres of the ``pool`` × ``pool`` blocks of a map max-pooled
    with ``ceil_mode`` (⌈G / pool⌉² of them)."""
    centre = size // 2
    blocks = -(-size // pool)
    start = torch.arange(blocks, dtype=torch.float32, device=gps.device) * pool
    index = (start + (start + pool - 1).clamp(max=size - 1)) / 2
    rows, cols = torch.meshgrid(index, index, indexing="ij")
    dx = (centre - rows).reshape(1, -1) * cell_size - gps[:, :1]
    dy = (centre - cols).reshape(1, -1) * cell_size - gps[:, 1:2]
    cos, sin = (v.view(-1, 1) for v in _unit(compass))
    return torch.stack([dx * cos + dy * sin, -dx * sin + dy * cos], dim=-1)


def pool_depth(
    depth: Tensor, size: tuple[int, int], geometry: MapGeometry
) -> tuple[Tensor, Tensor]:
    """Depth observations (N, H, W, 1) → planar metres and validity at feature resolution
    (N, h, w).

    Each feature pixel gets the mean depth of its valid image pixels (those not clipped at the
    far limit); it is valid when at least half of its pixels are (average pooling)."""
    observed = depth.permute(0, 3, 1, 2).float()
    planes = geometry.depth_metres(observed)
    valid = (~geometry.far(observed)).float()
    fraction = F.adaptive_avg_pool2d(valid, size)
    mean = F.adaptive_avg_pool2d(planes * valid, size) / fraction.clamp_min(1e-6)
    return mean[:, 0], (fraction >= 0.5)[:, 0]


def project_egocentric(
    features: Tensor, metres: Tensor, valid: Tensor, hfov_deg: float, cell_size: float
) -> Tensor:
    """MapNet-style projection of an image feature map onto the egocentric ground grid.

    ``features`` (N, C, h, w) ≥ 0 (post-ReLU), ``metres`` (N, h, w) planar depth, ``valid``
    (N, h, w) bool. Feature pixel (i, j) lands at ``ahead = depth``, ``left = -depth·x·tan(hfov/2)``
    with ``x ∈ (-1, 1)`` its column centre (pinhole camera; the pixel's row only sets the
    height, which the ground map ignores). Points outside the grid (beyond 5.2 m ahead or
    sideways) and invalid ones are dropped; features landing in the same cell are combined by
    max; cells nothing lands in hold 0. Returns (N, C, EGO_ROWS, EGO_COLS), differentiable
    w.r.t. ``features``.
    """
    n, channels, h, w = features.shape
    x = (torch.arange(w, dtype=metres.dtype, device=metres.device) + 0.5) / w * 2.0 - 1.0
    ahead = metres
    left = -metres * x.view(1, 1, w) * math.tan(math.radians(hfov_deg) / 2)
    row = EGO_ROWS - 1 - torch.floor(ahead / cell_size + 0.5)
    col = EGO_COLS // 2 - torch.floor(left / cell_size + 0.5)
    ok = valid & (ahead >= 0) & (row >= 0) & (col >= 0) & (col < EGO_COLS)
    cells = EGO_ROWS * EGO_COLS
    index = torch.where(ok, row * EGO_COLS + col, torch.full_like(row, cells)).long()
    index = index.reshape(n, 1, h * w).expand(n, channels, h * w)
    out = features.new_zeros(n, channels, cells + 1)  # the extra cell collects dropped points
    out = out.scatter_reduce(
        2, index, features.reshape(n, channels, h * w), "amax", include_self=True
    )
    return out[..., :cells].reshape(n, channels, EGO_ROWS, EGO_COLS)


@lru_cache(maxsize=4)
def _ego_sub_points(cell_size: float, device: torch.device) -> tuple[Tensor, Tensor]:
    """(ahead, left) metres of 2 × 2 sub-points of every egocentric cell, (P, 2), and the flat
    egocentric cell each belongs to, (P,)."""
    rows = torch.arange(EGO_ROWS, device=device).repeat_interleave(EGO_COLS)
    cols = torch.arange(EGO_COLS, device=device).repeat(EGO_ROWS)
    centre = torch.stack([EGO_ROWS - 1 - rows, EGO_COLS // 2 - cols], dim=-1).float() * cell_size
    quarter = cell_size / 4
    offsets = torch.tensor(
        [[-quarter, -quarter], [-quarter, quarter], [quarter, -quarter], [quarter, quarter]],
        device=device,
    )
    points = (centre.unsqueeze(1) + offsets).reshape(-1, 2)
    return points, torch.arange(EGO_ROWS * EGO_COLS, device=device).repeat_interleave(4)


WINDOW = 21
"""Side of the global-map window a registration touches, cells: the egocentric grid reaches
at most √(5.2² + 5.2²) + 0.4 < 8 m = 10 cells from the agent's cell."""


def register(
    global_map: Tensor, ego: Tensor, gps: Tensor, compass: Tensor, cell_size: float
) -> Tensor:
    """R(m_t, M_t | p_t): merge the egocentric grid ``ego`` (B, C, EGO_ROWS, EGO_COLS) into
    ``global_map`` (B, C, G, G) by element-wise max, for agents at ``gps``/``compass``.

    Each egocentric cell is splatted at 2 × 2 sub-points (0.4 m apart) into the global cells
    they fall in: no egocentric cell is lost and a rotated grid leaves no holes (a cell
    straddling a border is written on both sides). Points off the map are dropped. The max
    includes the old map (zero is neutral for non-negative features); gradients flow to
    whichever value won. Only a ``WINDOW``² window around the agent is merged (the full-map
    scatter-max was 4× slower to back-propagate); the window is shifted to stay on the map."""
    batch, channels, size, _ = global_map.shape
    window = min(WINDOW, size)
    points, owner = _ego_sub_points(cell_size, global_map.device)
    cos, sin = (v.view(-1, 1) for v in _unit(compass))
    ahead, left = points[:, 0], points[:, 1]
    x = gps[:, :1] + ahead * cos - left * sin
    y = gps[:, 1:2] + ahead * sin + left * cos
    centre = size // 2
    row = torch.floor(centre + 0.5 - x / cell_size).long()  # (B, P)
    col = torch.floor(centre + 0.5 - y / cell_size).long()
    agent_row, agent_col, _ = world_cell(gps, size, cell_size)
    top = (agent_row - window // 2).clamp(0, size - window).unsqueeze(1)  # (B, 1)
    first = (agent_col - window // 2).clamp(0, size - window).unsqueeze(1)
    row, col = row - top, col - first
    inside = (row >= 0) & (row < window) & (col >= 0) & (col < window)
    local = torch.where(inside, row * window + col, torch.zeros_like(row))
    source = ego.flatten(2)[:, :, owner] * inside.unsqueeze(1).to(ego.dtype)
    offsets = torch.arange(window, device=gps.device)
    cells = ((top + offsets).unsqueeze(2) * size + (first + offsets).unsqueeze(1)).flatten(1)
    cells = cells.unsqueeze(1).expand(batch, channels, window * window)
    flat = global_map.flatten(2)
    old = flat.gather(2, cells)
    local = local.unsqueeze(1).expand(batch, channels, local.shape[1])
    # the map keeps its dtype when the projection ran under autocast (--mixed-precision)
    merged = old.scatter_reduce(2, local, source.to(old.dtype), "amax", include_self=True)
    return flat.scatter(2, cells, merged).view(batch, channels, size, size)
