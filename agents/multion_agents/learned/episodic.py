"""Episodic-memory agents (paper §4.2 "Implicit memory baselines"): FRMQN and SMT.

Both keep the embeddings of the last ``M`` observations of the episode in a ring buffer (the
state) and read it with attention. The state is all zeros when empty: ``count`` (B, 1) is the
number of writes so far (the next slot is ``count mod M``) and ``valid`` (B, M) marks written
slots, both floats.

The observation embedding is the policy's ``query = [v_i, v_g, v_a]`` (the CNN embedding of
RGB-D, the goal and the previous action): the paper uses "the same CNN as in our other agent
models to produce the observation embeddings".
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from gymnasium import spaces
from torch import Tensor, nn

from multion_agents.learned.memory import Batch, Memory, State
from multion_agents.learned.policy import ACTION_EMBED_DIM, GOAL_EMBED_DIM, HIDDEN_SIZE

IMAGE_EMBED_DIM = 512
"""``ImageEncoder``'s default embedding width, as RecurrentPolicy builds it."""

MEMORY_SIZE = 64
"""Observations remembered (the last M steps of the episode)."""


def ring_write(buffer: Tensor, count: Tensor, item: Tensor) -> Tensor:
    """``buffer`` (B, M, D) with ``item`` (B, D) written at slot ``count mod M`` (count (B, 1))."""
    slot = F.one_hot(count[:, 0].long() % buffer.shape[1], buffer.shape[1]).to(buffer.dtype)
    slot = slot.unsqueeze(-1)
    return buffer * (1.0 - slot) + item.unsqueeze(1) * slot


def ring_mark(valid: Tensor, count: Tensor) -> Tensor:
    """``valid`` (B, M) with the slot written at ``count`` marked."""
    slot = F.one_hot(count[:, 0].long() % valid.shape[1], valid.shape[1]).to(valid.dtype)
    return torch.maximum(valid, slot)


def masked_attention(query: Tensor, keys: Tensor, values: Tensor, valid: Tensor) -> Tensor:
    """Scaled dot-product attention of ``query`` (B, D) over ``keys``/``values`` (B, M, ·),
    ignoring slots where ``valid`` (B, M) is 0; zeros where no slot is valid (no NaN)."""
    present = valid > 0
    scores = torch.einsum("bmd,bd->bm", keys, query) / math.sqrt(query.shape[-1])
    weights = torch.softmax(scores.masked_fill(~present, -1e9), dim=1) * present
    return torch.einsum("bm,bmd->bd", weights, values)


class FRMQN(Memory):
    """FRMQN (Oh et al. 2016, "Control of Memory, Active Perception, and Action in Minecraft").

    Paper (MultiON §4.2): observation embeddings of the previous steps are stored in a memory
    as key/value pairs and read by soft attention. Oh et al.: keys and values are linear maps of
    the last M frame embeddings; the read's query is a context vector from an LSTM fed with the
    current embedding and the previous read ("feedback recurrent"); the read and the context
    feed the policy.

    Ours: the policy's GRU is the context recurrence (it took the previous read as input), so
    the query is a linear map of the current ``[v_i, v_g, v_a]`` and the GRU state ``h_{t-1}``.
    The current observation is written after the read, so the read covers the M previous
    steps; at an episode's first step it is zero. ``v_m`` is the 256-d read.
    """

    reads_hidden = True

    def __init__(
        self,
        observation_dim: int,
        hidden_dim: int = HIDDEN_SIZE,
        memory_size: int = MEMORY_SIZE,
        key_dim: int = 128,
        out_dim: int = 256,
    ):
        super().__init__()
        self.memory_size, self.key_dim, self.out_dim = memory_size, key_dim, out_dim
        self.observation_dim = observation_dim
        self.key = nn.Linear(observation_dim, key_dim)
        self.value = nn.Linear(observation_dim, out_dim)
        self.context = nn.Linear(observation_dim + hidden_dim, key_dim)

    def initial_state(self, batch: int, device: torch.device) -> State:
        m = self.memory_size
        return {
            "keys": torch.zeros(batch, m, self.key_dim, device=device),
            "values": torch.zeros(batch, m, self.out_dim, device=device),
            "valid": torch.zeros(batch, m, device=device),
            "count": torch.zeros(batch, 1, device=device),
        }

    def step(self, frame: Batch, query: Tensor, state: State) -> tuple[Tensor, State]:
        observation = query[:, : self.observation_dim]
        read = masked_attention(self.context(query), state["keys"], state["values"], state["valid"])
        count = state["count"]
        new_state = {
            "keys": ring_write(state["keys"], count, self.key(observation)),
            "values": ring_write(state["values"], count, self.value(observation)),
            "valid": ring_mark(state["valid"], count),
            "count": count + 1.0,
        }
        return read, new_state


class _Block(nn.Module):
    """Post-norm transformer block: attention of ``x`` over ``memory``, then a feed-forward."""

    def __init__(self, dim: int, heads: int, hidden: int):
        super().__init__()
        self.attention = nn.MultiheadAttention(dim, heads, batch_first=True)
        self.norm1, self.norm2 = nn.LayerNorm(dim), nn.LayerNorm(dim)
        self.feed_forward = nn.Sequential(nn.Linear(dim, hidden), nn.ReLU(), nn.Linear(hidden, dim))

    def forward(self, x: Tensor, memory: Tensor, ignore: Tensor) -> Tensor:
        attended, _ = self.attention(x, memory, memory, key_padding_mask=ignore, need_weights=False)
        x = self.norm1(x + attended)
        out: Tensor = self.norm2(x + self.feed_forward(x))
        return out


class SMT(Memory):
    """SMT, the Scene Memory Transformer (Fang et al. 2019).

    Paper (MultiON §4.2): each observation's embedding is stored in memory and an
    encoder-decoder network retrieves information from it. Fang et al.: the memory holds every
    past observation embedding (with its pose relative to the current one); a transformer encoder
    self-attends over the memory and a decoder attends from the current observation over the
    encoded memory.

    Ours: the last M = 64 embeddings, projected to d = 128 (no pose: the MultiON paper stores
    observation embeddings only); one self-attention encoder block over the memory and one
    cross-attention decoder block from the current embedding, 4 heads, recomputed each step
    because the memory changes. The current observation is written first, so the memory is
    never empty when read; slots never written are masked (and a fully empty memory, which
    nn.MultiheadAttention would turn into NaN, reads as zeros). ``v_m`` is 256-d.
    """

    def __init__(
        self,
        query_dim: int,
        memory_size: int = MEMORY_SIZE,
        dim: int = 128,
        heads: int = 4,
        out_dim: int = 256,
    ):
        super().__init__()
        self.memory_size, self.dim, self.out_dim = memory_size, dim, out_dim
        self.embed = nn.Sequential(nn.Linear(query_dim, dim), nn.ReLU())
        self.encoder = _Block(dim, heads, 2 * dim)
        self.decoder = _Block(dim, heads, 2 * dim)
        self.out = nn.Sequential(nn.Linear(dim, out_dim), nn.ReLU())

    def initial_state(self, batch: int, device: torch.device) -> State:
        return {
            "memory": torch.zeros(batch, self.memory_size, self.dim, device=device),
            "valid": torch.zeros(batch, self.memory_size, device=device),
            "count": torch.zeros(batch, 1, device=device),
        }

    def read(self, current: Tensor, memory: Tensor, valid: Tensor) -> Tensor:
        """The decoder's output (B, dim) for ``current`` (B, dim) over ``memory`` (B, M, dim)."""
        present = valid > 0
        anything = present.any(dim=1)
        ignore = ~present
        ignore[:, 0] &= anything  # keep one key in empty memories: masked rows would give NaN
        encoded = self.encoder(memory, memory, ignore)
        decoded = self.decoder(current.unsqueeze(1), encoded, ignore)[:, 0]
        read: Tensor = decoded * anything.unsqueeze(1).to(decoded.dtype)
        return read

    def step(self, frame: Batch, query: Tensor, state: State) -> tuple[Tensor, State]:
        current = self.embed(query)
        count = state["count"]
        memory = ring_write(state["memory"], count, current)
        valid = ring_mark(state["valid"], count)
        read = self.read(current, memory, valid)
        return self.out(read), {"memory": memory, "valid": valid, "count": count + 1.0}


def policy_query_dim(observation_space: spaces.Dict) -> int:
    """Width of the policy's ``[v_i, v_g, v_a]`` for ``observation_space`` (see RecurrentPolicy:
    a 512-d image embedding when it sees rgb or depth, 32-d goal and action embeddings)."""
    sees = "rgb" in observation_space.spaces or "depth" in observation_space.spaces
    return IMAGE_EMBED_DIM * sees + GOAL_EMBED_DIM + ACTION_EMBED_DIM


def build_frmqn(
    observation_space: spaces.Dict, geometry: object = None, hidden_size: int = HIDDEN_SIZE
) -> FRMQN:
    return FRMQN(policy_query_dim(observation_space), hidden_size)


def build_smt(
    observation_space: spaces.Dict, geometry: object = None, hidden_size: int = HIDDEN_SIZE
) -> SMT:
    return SMT(policy_query_dim(observation_space))
