"""Encoders shared by the learned agents (paper §4.1, Figure 2).

The RGB-D CNN is habitat-baselines' ``SimpleCNN`` (the reference code's visual encoder): three
convolutions and a linear layer to 512. Map inputs (oracle maps, learned maps) become 16-d
learned embeddings per channel, then a small CNN and a linear layer to 256.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor, nn

from multion.config.ranges import ConfigError
from multion_client.constants import NUM_CATEGORIES

EMBED_DIM = 16
"""Per-channel embedding width of map cells (paper: 16-d occupancy and category embeddings)."""
NUM_OCCUPANCY_VALUES = 3  # unknown/outside, free, occupied (multion_client.constants.MAP_*)
NUM_CATEGORY_VALUES = NUM_CATEGORIES + 1  # "no goal" + k categories (stored as category + 1)


def conv_output_size(size: int, kernel: int, stride: int) -> int:
    return (size - kernel) // stride + 1


class ImageEncoder(nn.Module):
    """RGB-D (or RGB, or depth) frames → feature map ``i_t`` and a 512-d embedding ``v_i``.

    Accepts ``rgb`` (B, H, W, 3) uint8 and/or ``depth`` (B, H, W, 1) float in [0, 1].
    """

    def __init__(self, image_size: int, use_rgb: bool, use_depth: bool, out_dim: int = 512):
        super().__init__()
        if not (use_rgb or use_depth):
            raise ValueError("ImageEncoder needs rgb, depth or both")
        self.use_rgb, self.use_depth = use_rgb, use_depth
        channels = 3 * use_rgb + use_depth
        self.features = nn.Sequential(
            nn.Conv2d(channels, 32, 8, stride=4),
            nn.ReLU(),
            nn.Conv2d(32, 64, 4, stride=2),
            nn.ReLU(),
            nn.Conv2d(64, 32, 3, stride=1),
            nn.ReLU(),
        )
        side = image_size
        for kernel, stride in ((8, 4), (4, 2), (3, 1)):
            side = conv_output_size(side, kernel, stride)
        if side < 1:
            raise ConfigError(f"images of {image_size} px are too small for the CNN (min 36)")
        self.feature_channels, self.feature_side = 32, side
        self.embed = nn.Sequential(nn.Flatten(), nn.Linear(32 * side * side, out_dim), nn.ReLU())
        self.out_dim = out_dim

    def forward(self, rgb: Tensor | None, depth: Tensor | None) -> tuple[Tensor, Tensor]:
        planes = []
        if self.use_rgb:
            assert rgb is not None
            planes.append(rgb.permute(0, 3, 1, 2).float() / 255.0)
        if self.use_depth:
            assert depth is not None
            planes.append(depth.permute(0, 3, 1, 2).float())
        feature_map = self.features(torch.cat(planes, dim=1))
        return feature_map, self.embed(feature_map)


class MapCNN(nn.Module):
    """An egocentric map (B, C, S, S) of embeddings → a 256-d vector ``v_m``."""

    def __init__(self, in_channels: int, size: int, out_dim: int = 256):
        super().__init__()
        layers: list[nn.Module] = []
        channels, side = in_channels, size
        # stride-2 convolutions while the map is large, then one 3×3 (the map is small: 7–51 cells)
        for out_channels in (64, 64):
            if side >= 9:
                layers += [nn.Conv2d(channels, out_channels, 3, stride=2), nn.ReLU()]
                channels, side = out_channels, conv_output_size(side, 3, 2)
        layers += [nn.Conv2d(channels, 32, 3, stride=1, padding=1), nn.ReLU(), nn.Flatten()]
        self.net = nn.Sequential(*layers, nn.Linear(32 * side * side, out_dim), nn.ReLU())
        self.out_dim = out_dim
        # channels-last kernels and maps: the same function, and on a CPU (oneDNN) 2.2× faster
        # forward and backward than a (B, C, S, S)-contiguous crop (docs/training-speed.md)
        for kernel in self.net.parameters():
            if kernel.dim() == 4:  # convolution kernels (Module.to's stubs lack memory_format)
                kernel.data = kernel.data.contiguous(memory_format=torch.channels_last)

    def forward(self, grid: Tensor) -> Tensor:
        out: Tensor = self.net(grid.contiguous(memory_format=torch.channels_last))
        return out

    def forward_cells(self, cells: Tensor, tables: Sequence[Tensor]) -> Tensor:
        """``self(embedded map)`` for integer ``cells`` (B, S, S, K) whose channel ``k`` is
        embedded by ``tables[k]``, with the embedding folded into the first convolution
        (:func:`embed_and_convolve`)."""
        first = self.net[0]
        assert isinstance(first, nn.Conv2d)
        out: Tensor = self.net[1:](embed_and_convolve(cells, tables, first))
        return out


def embed_and_convolve(cells: Tensor, tables: Sequence[Tensor], conv: nn.Conv2d) -> Tensor:
    """``conv`` over the embedded map ``cat_k(tables[k][cells[..., k]])``, computed as one
    convolution over the one-hot cells with each table folded into the kernel.

    A convolution is linear in its input, so the two are the same function with the same
    gradients (up to rounding); this one skips the embedding's scattered backward and the
    gradient of the convolution's input, which dominated the PPO update of the map agents.
    """
    weights = conv.weight.split([t.shape[1] for t in tables], dim=1)
    kernel = torch.cat(
        [torch.einsum("odij,vd->ovij", w, t) for w, t in zip(weights, tables, strict=True)], dim=1
    )
    one_hot = torch.cat(
        [
            nn.functional.one_hot(cells[..., k], t.shape[0]).to(kernel.dtype)
            for k, t in enumerate(tables)
        ],
        dim=-1,
    ).permute(0, 3, 1, 2)
    return nn.functional.conv2d(one_hot, kernel, conv.bias, conv.stride, conv.padding)


class SemanticMapEmbedding(nn.Module):
    """Integer map cells (B, S, S, 2) = (occupancy, category + 1) → (B, C, S, S) embeddings.

    ``channels`` picks what the agent sees: ``"occ"``, ``"obj"`` or ``"occ+obj"`` (paper Table 3).
    """

    def __init__(self, channels: str = "occ+obj"):
        super().__init__()
        if channels not in ("occ", "obj", "occ+obj"):
            raise ValueError(f"map channels must be occ, obj or occ+obj, got {channels!r}")
        self.use_occupancy = "occ" in channels
        self.use_category = "obj" in channels
        self.occupancy = nn.Embedding(NUM_OCCUPANCY_VALUES, EMBED_DIM)
        self.category = nn.Embedding(NUM_CATEGORY_VALUES, EMBED_DIM)
        self.out_channels = EMBED_DIM * (self.use_occupancy + self.use_category)

    def forward(self, cells: Tensor) -> Tensor:
        indices, tables = self.lookups(cells)
        parts = [table[indices[..., k]] for k, table in enumerate(tables)]
        return torch.cat(parts, dim=-1).permute(0, 3, 1, 2)

    def lookups(self, cells: Tensor) -> tuple[Tensor, list[Tensor]]:
        """The clamped indices (B, S, S, K) of the channels in use and their tables, for
        :meth:`MapCNN.forward_cells`."""
        cells = cells.long()
        columns, tables = [], []
        if self.use_occupancy:
            columns.append(cells[..., 0].clamp(0, NUM_OCCUPANCY_VALUES - 1))
            tables.append(self.occupancy.weight)
        if self.use_category:
            columns.append(cells[..., 1].clamp(0, NUM_CATEGORY_VALUES - 1))
            tables.append(self.category.weight)
        return torch.stack(columns, dim=-1), tables
