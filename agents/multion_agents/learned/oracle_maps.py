"""Memories for the oracle-map agents (paper §4.2 and the supplement's ablations).

The server renders the egocentric crop of the oracle map (``oracle_map``) or of its revealed
part (``oracle_ego_map``), so these memories are reactive: each step embeds the crop it sees
and the GRU remembers the rest.
"""

from __future__ import annotations

from gymnasium import spaces
from torch import Tensor

from multion_agents.learned.encoders import MapCNN, SemanticMapEmbedding
from multion_agents.learned.memory import Batch, Memory, State


class OracleMapMemory(Memory):
    """``v_m`` from the oracle (ego) map crop.

    ``channels`` is ``occ``, ``obj`` or ``occ+obj``; ``dynamic`` keeps only the *current* goal
    in the object channel (the supplement's DynamicOracleMap / DynamicOracleEgoMap), which
    turns m-ON into m successive 1-ON tasks.
    """

    def __init__(
        self,
        observation_space: spaces.Dict,
        crop_size: int,
        sensor: str = "oracle_map",
        channels: str = "occ+obj",
        dynamic: bool = False,
    ) -> None:
        super().__init__()
        if sensor not in ("oracle_map", "oracle_ego_map"):
            raise ValueError(f"OracleMapMemory reads oracle_map or oracle_ego_map, not {sensor!r}")
        self.sensor, self.dynamic = sensor, dynamic
        self.sensors = (sensor,)
        self.embedding = SemanticMapEmbedding(channels)
        if sensor in observation_space.spaces:
            shape = observation_space[sensor].shape
            assert shape is not None  # a map space is a Box
            if shape[0] != crop_size:
                raise ValueError(
                    f"{sensor} is {shape[0]} cells wide but maps.ego_size is {crop_size}"
                )
        self.cnn = MapCNN(self.embedding.out_channels, crop_size)
        self.out_dim = self.cnn.out_dim

    def precompute(self, frames: Batch, image_features: Tensor | None) -> Batch:
        cells = frames[self.sensor].long()
        if self.dynamic:
            current = frames["goal"].long().view(-1, 1, 1) + 1
            category = cells[..., 1]
            cells = cells.clone()
            cells[..., 1] = category * (category == current)
        return {"map_embedding": self.cnn.forward_cells(*self.embedding.lookups(cells))}

    def step(self, frame: Batch, query: Tensor, state: State) -> tuple[Tensor, State]:
        return frame["map_embedding"], state
