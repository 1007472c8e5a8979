"""Memories of the learned-map agents (paper §4.2 "Learned map agents", supplement §B).

Each keeps a global map of 0.8 m cells in the episode's start frame as its state (see
:mod:`multion_agents.learned.map_ops` for the frames), built from the agent's own sensing and
pose (``gps``, ``compass``), and reads an egocentric, rotated crop of it with a small CNN:

* :class:`ObjRecogMap`: a (k+1)-way classifier on the image features says which goal object is
  in view; its prediction is written at the agent's cell.
* :class:`ProjNeuralMap`: image features are projected onto the ground with depth (MapNet) and
  max-merged into a neural global map.
* :class:`EgoMap`: the same neural map, also read with attention (Beeching et al. 2020).

Cell size, crop size, field of view and depth range are those of the env config the agent is
trained with (:class:`~multion_agents.learned.map_ops.MapGeometry`, stored in the checkpoint):
the crop read by the CNN is ``maps.ego_size`` cells, like the oracle maps'. Where we differ from
the paper: the global map is 63 × 63 cells (50 m at 0.8 m), not 300 × 300, since our houses are
smaller.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch
import torch.nn.functional as F
from gymnasium import spaces
from torch import Tensor, nn

from multion_agents.learned import map_ops
from multion_agents.learned.encoders import EMBED_DIM, NUM_CATEGORY_VALUES, MapCNN
from multion_agents.learned.episodic import policy_query_dim
from multion_agents.learned.map_ops import MapGeometry
from multion_agents.learned.memory import Batch, MapMemory, State
from multion_agents.learned.policy import HIDDEN_SIZE

RECOGNITION_DISTANCE = 2.5
"""A goal counts as "in view" for the recognition label within this distance, metres."""


def recognition_label(goal_mask: Tensor, depth: Tensor, geometry: MapGeometry) -> Tensor:
    """ObjRecogMap's training target per frame: ``c + 1`` for the nearest visible goal of
    category ``c`` if it is within 2.5 m, else 0 ("no goal").

    ``goal_mask`` (N, H, W) holds category + 1 per pixel (0: no goal); ``depth`` (N, H, W, 1) is
    normalised planar depth. Pixels are in the 79° field of view by construction; "within
    2.5 m" uses the pixel's planar depth (the nearest pixel of each goal)."""
    mask = goal_mask.long().flatten(1)
    metres = geometry.depth_metres(depth.float().flatten(1))
    near = (mask > 0) & (metres <= RECOGNITION_DISTANCE)
    distance = torch.where(near, metres, torch.full_like(metres, math.inf))
    nearest = distance.argmin(dim=1, keepdim=True)
    label = mask.gather(1, nearest).squeeze(1)
    return torch.where(near.any(dim=1), label, torch.zeros_like(label))


def balancing_weights(label: Tensor, classes: int) -> Tensor:
    """Cross-entropy class weights that give each class present in ``label`` the same total
    weight, the mean weight per frame staying 1 (classes absent get 0)."""
    counts = torch.bincount(label, minlength=classes).to(torch.float32)
    present = counts > 0
    weights = torch.zeros(classes, device=label.device)
    weights[present] = label.numel() / (present.sum() * counts[present])
    return weights


class ObjRecogMap(MapMemory):
    """ObjRecogMap: a global map of recognised goal categories (supplement "ObjRecogMap").

    Paper: a (k+1)-way classifier on the current frame, supervised with cross-entropy against
    the nearest goal within the 79° FOV and 2.5 m ("no goal" otherwise), writes its predicted
    category at the agent's cell unless it predicts "no goal"; each cell holds a 16-d embedding
    of one of k+1 categories; the egocentric crop is read by a CNN.

    Ours: the classifier is a head on the shared RGB-D CNN's feature map (1×1 conv, spatial max,
    linear), so the auxiliary loss also trains that CNN; classes use the stored-value convention
    of :data:`~multion_agents.learned.encoders.NUM_CATEGORY_VALUES` (0 "no goal", c+1 category
    c). The map (state ``map``, (B, G, G) floats) stores category + 1, 0 for empty. The argmax
    written to the map carries no gradient (as in the paper). ``dynamic`` (the supplement's
    DynamicObjRecogMap) keeps only the current goal's category when reading the map.
    """

    sensors = ("gps", "compass")
    train_sensors = ("goal_mask",)

    def __init__(
        self,
        observation_space: spaces.Dict,
        geometry: MapGeometry,
        dynamic: bool = False,
    ) -> None:
        super().__init__()
        self.geometry, self.dynamic = geometry, dynamic
        self.global_size, self.crop_size = geometry.global_size, geometry.crop_size
        self.classifier = nn.Sequential(
            nn.Conv2d(32, 64, 1),
            nn.ReLU(),
            nn.AdaptiveMaxPool2d(1),
            nn.Flatten(),
            nn.Linear(64, NUM_CATEGORY_VALUES),
        )
        self.embedding = nn.Embedding(NUM_CATEGORY_VALUES, EMBED_DIM)
        self.cnn = MapCNN(EMBED_DIM, self.crop_size)
        self.out_dim = self.cnn.out_dim
        self.balanced = False
        """Weigh the recogniser's classes equally in each batch (``--balanced-recognition``):
        most frames show no goal, and a recogniser that always answers "no goal" is nearly
        right (its loss stayed at 0.01-0.13 in the published run, docs/learned.md). The paper
        weighs every frame alike (False)."""

    def initial_state(self, batch: int, device: torch.device) -> State:
        return {"map": torch.zeros(batch, self.global_size, self.global_size, device=device)}

    def precompute(self, frames: Batch, image_features: Tensor | None) -> Batch:
        if image_features is None:
            raise ValueError("ObjRecogMap needs the RGB-D image features")
        logits = self.classifier(image_features)
        return {"recog_logits": logits, "recog_prediction": logits.detach().argmax(1).float()}

    def write(self, grid: Tensor, prediction: Tensor, gps: Tensor) -> Tensor:
        """The map (B, G, G) with ``prediction`` (B,) written at each agent's cell (unless 0)."""
        row, col, inside = map_ops.world_cell(gps, self.global_size, self.geometry.cell_size)
        index = (row * self.global_size + col).clamp(0, self.global_size**2 - 1)
        cell = F.one_hot(index, self.global_size**2).bool().view_as(grid)
        write = cell & (inside & (prediction > 0)).view(-1, 1, 1)
        return torch.where(write, prediction.view(-1, 1, 1).to(grid.dtype), grid)

    def advance(self, frame: Batch, state: State) -> tuple[Tensor, State]:
        """Write this step's prediction; the view is the crop's stored values (B, S, S)."""
        gps, compass = frame["gps"].float(), frame["compass"].float()
        grid = self.write(state["map"], frame["recog_prediction"], gps)
        crop = map_ops.egocentric_crop(
            grid.unsqueeze(1), gps, compass, self.crop_size, self.geometry.cell_size
        )
        return crop[:, 0], {"map": grid}

    def read(self, views: Tensor, frames: Batch) -> Tensor:
        cells = views.round().long().clamp(0, NUM_CATEGORY_VALUES - 1)
        if self.dynamic:
            current = frames["goal"].long().view(-1, 1, 1) + 1
            cells = cells * (cells == current)
        features: Tensor = self.cnn(self.embedding(cells).permute(0, 3, 1, 2))
        return features

    def auxiliary_loss(self, frames: Batch, precomputed: Batch) -> Tensor | None:
        if "goal_mask" not in frames or "depth" not in frames:
            return None
        label = recognition_label(frames["goal_mask"], frames["depth"], self.geometry)
        weight = balancing_weights(label, NUM_CATEGORY_VALUES) if self.balanced else None
        return F.cross_entropy(precomputed["recog_logits"], label, weight=weight)


class ProjNeuralMap(MapMemory):
    """ProjNeuralMap: image features projected to the ground and max-merged into a global map.

    Paper (MapNet projection, supplement): the image features ``i_t`` are projected with the
    depth frame downsampled to their resolution onto a 7 × 13 egocentric grid (5.6 m ahead and to
    both sides, agent at the mid-bottom), points beyond 5.6 m dropped; ``R(m_t, M_t | p_t)``
    registers it into the global map with element-wise max; the egocentric crop of the map is
    read by a CNN.

    Ours: the 32-channel feature map of the shared RGB-D CNN; depth is average-pooled over its
    valid (not far-clipped) pixels; the agent sits at the centre of the grid's bottom-middle
    cell, so it spans 5.2 m ahead (the sensor sees 5 m); the registration splats each
    egocentric cell at 2 × 2 sub-points, so 30° turns leave no holes (see
    :func:`~multion_agents.learned.map_ops.register`). The global map
    (state ``map``, (B, 32, G, G)) starts at zero, neutral for the max of post-ReLU features;
    the map is differentiable w.r.t. the features through time.
    """

    sensors = ("depth", "gps", "compass")

    def __init__(
        self,
        observation_space: spaces.Dict,
        geometry: MapGeometry,
        channels: int = 32,
    ) -> None:
        super().__init__()
        self.geometry, self.channels = geometry, channels
        self.global_size, self.crop_size = geometry.global_size, geometry.crop_size
        self.cnn = MapCNN(channels, self.crop_size)
        self.out_dim = self.cnn.out_dim

    def initial_state(self, batch: int, device: torch.device) -> State:
        size = self.global_size
        return {"map": torch.zeros(batch, self.channels, size, size, device=device)}

    def precompute(self, frames: Batch, image_features: Tensor | None) -> Batch:
        if image_features is None:
            raise ValueError(f"{type(self).__name__} needs the RGB-D image features")
        geometry = self.geometry
        height, width = image_features.shape[-2:]
        metres, valid = map_ops.pool_depth(frames["depth"], (height, width), geometry)
        ego = map_ops.project_egocentric(
            image_features, metres, valid, geometry.hfov_deg, geometry.cell_size
        )
        return {"ego_map": ego}

    def update(self, frame: Batch, state: State) -> tuple[Tensor, Tensor, Tensor]:
        """Register this step's egocentric map: the new global map, gps and compass."""
        gps, compass = frame["gps"].float(), frame["compass"].float()
        grid = map_ops.register(
            state["map"], frame["ego_map"], gps, compass, self.geometry.cell_size
        )
        return grid, gps, compass

    def advance(self, frame: Batch, state: State) -> tuple[Tensor, State]:
        """Register this step's egocentric map; the view is the global map's crop."""
        grid, gps, compass = self.update(frame, state)
        crop = map_ops.egocentric_crop(grid, gps, compass, self.crop_size, self.geometry.cell_size)
        return crop, {"map": grid}

    def read(self, views: Tensor, frames: Batch) -> Tensor:
        features: Tensor = self.cnn(views)
        return features


class EgoMap(ProjNeuralMap):
    """EgoMap (Beeching et al. 2020): the ProjNeuralMap global map, also read with attention.

    Paper: like ProjNeuralMap but with an attention-based read. Beeching et al. read their
    egocentric map with a conv network and with attention whose query comes from the agent's
    recurrent state, and keys/values from the map's features and cell coordinates.

    Ours: the query is a projection of this step's ``[v_i, v_g, v_a]`` and the GRU state
    ``h_{t-1}``; keys and values are 1×1 projections of the features of every cell of the
    global map max-pooled 2 × 2 (32 × 32 cells of 1.6 m: full resolution made this model 2×
    slower than ProjNeuralMap) plus a learned encoding (Fourier features) of the cell's position
    relative to the agent;
    cells never written (all-zero features) are ignored, and an empty map reads as zeros. The
    attention read is concatenated with the crop CNN's output and projected to 256.
    """

    reads_hidden = True
    frequencies: Tensor  # a buffer (``register_buffer`` in ``__init__``)

    def __init__(
        self,
        observation_space: spaces.Dict,
        geometry: MapGeometry,
        query_dim: int,
        channels: int = 32,
        attention_dim: int = 32,
        frequencies: int = 6,
        attention_pool: int = 2,
    ) -> None:
        super().__init__(observation_space, geometry, channels)
        self.attention_dim, self.attention_pool = attention_dim, attention_pool
        wavelengths = 2.0 ** torch.arange(frequencies, dtype=torch.float32)
        self.register_buffer(
            "frequencies",
            math.pi * wavelengths / (self.global_size * geometry.cell_size),
            persistent=False,
        )
        self.query = nn.Linear(query_dim, attention_dim)
        self.key_value = nn.Linear(channels, 2 * attention_dim)
        self.position = nn.Linear(2 + 4 * frequencies, 2 * attention_dim)
        self.out = nn.Sequential(nn.Linear(self.cnn.out_dim + attention_dim, 256), nn.ReLU())
        self.out_dim = 256

    def positional_features(self, relative: Tensor) -> Tensor:
        """(…, 2) metres → (…, 2 + 4F): scaled coordinates and their sines and cosines."""
        scaled = relative.unsqueeze(-1) * self.frequencies
        scale = self.global_size * self.geometry.cell_size / 2
        return torch.cat([relative / scale, scaled.sin().flatten(-2), scaled.cos().flatten(-2)], -1)

    def attend(self, grid: Tensor, gps: Tensor, compass: Tensor, query: Tensor) -> Tensor:
        """Attention read (B, attention_dim) of ``grid`` (B, C, G, G), max-pooled by
        ``attention_pool``; zeros for an empty map."""
        if self.attention_pool > 1:
            grid = F.max_pool2d(grid, self.attention_pool, ceil_mode=True)
        cells = grid.flatten(2).transpose(1, 2)  # (B, N, C)
        written = cells.detach().amax(dim=2) > 0
        relative = map_ops.relative_cell_positions(
            gps, compass, self.global_size, self.geometry.cell_size, self.attention_pool
        )
        keys, values = (
            self.key_value(cells) + self.position(self.positional_features(relative))
        ).chunk(2, -1)
        scores = torch.einsum("bnd,bd->bn", keys, self.query(query)) / math.sqrt(self.attention_dim)
        weights = torch.softmax(scores.masked_fill(~written, -1e9), dim=1) * written
        return torch.einsum("bn,bnd->bd", weights, values)

    def step(self, frame: Batch, query: Tensor, state: State) -> tuple[Tensor, State]:
        grid, gps, compass = self.update(frame, state)
        crop = map_ops.egocentric_crop(grid, gps, compass, self.crop_size, self.geometry.cell_size)
        read = self.attend(grid, gps, compass, query)
        return self.out(torch.cat([self.cnn(crop), read], dim=1)), {"map": grid}


def obj_recog_map(
    dynamic: bool = False,
) -> Callable[[spaces.Dict, MapGeometry, int], ObjRecogMap]:
    """Builder of an :class:`ObjRecogMap` (``dynamic``: DynamicObjRecogMap) for models.py."""

    def build(
        observation_space: spaces.Dict, geometry: MapGeometry, hidden_size: int = HIDDEN_SIZE
    ) -> ObjRecogMap:
        return ObjRecogMap(observation_space, geometry, dynamic=dynamic)

    return build


def build_proj_neural_map(
    observation_space: spaces.Dict, geometry: MapGeometry, hidden_size: int = HIDDEN_SIZE
) -> ProjNeuralMap:
    return ProjNeuralMap(observation_space, geometry)


def build_ego_map(
    observation_space: spaces.Dict, geometry: MapGeometry, hidden_size: int = HIDDEN_SIZE
) -> EgoMap:
    query_dim = policy_query_dim(observation_space) + hidden_size
    return EgoMap(observation_space, geometry, query_dim)
