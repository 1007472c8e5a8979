"""The memory contract of the learned agents: what makes one agent's ``v_m`` (paper §4.1).

A :class:`Memory` keeps its per-episode state (a map, a list of past embeddings) in a dict of
tensors whose first dimension is the environment; **an all-zero state is the empty state**, so
:class:`~multion_agents.learned.policy.RecurrentPolicy` clears a finished episode's memory by
multiplying its state by zero. :class:`MapMemory` splits a step into a sequential update and a
read that can be batched over a whole sequence.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import torch
from torch import Tensor, nn

State = dict[str, Tensor]
Batch = dict[str, Tensor]


class Memory(nn.Module, ABC):
    """What distinguishes one agent from another: how ``v_m`` is made.

    ``sensors`` are the observation keys the memory reads when acting; ``train_sensors`` the
    extra keys it needs only to compute an auxiliary loss during training (e.g. ``goal_mask``).
    """

    sensors: tuple[str, ...] = ()
    train_sensors: tuple[str, ...] = ()
    out_dim: int = 0
    reads_hidden: bool = False
    """True: ``step``'s query is ``[v_i, v_g, v_a, h_{t-1}]``, with the GRU state before the step
    (zero at an episode's first step), as in FRMQN and EgoMap, whose reads are queried by the
    agent's recurrent state. The memory and the GRU then advance together, one step at a time."""

    def initial_state(self, batch: int, device: torch.device) -> State:
        """The empty memory of ``batch`` environments (all zeros), on ``device``."""
        return {}

    def precompute(self, frames: Batch, image_features: Tensor | None) -> Batch:
        """Per-frame work that does not depend on the state, batched over all T·B frames."""
        return {}

    @abstractmethod
    def step(self, frame: Batch, query: Tensor, state: State) -> tuple[Tensor, State]:
        """One time step for B environments: ``frame`` holds the step's observations and
        precomputed tensors, ``query`` the step's ``[v_i, v_g, v_a]``. Returns ``v_m`` (B,
        out_dim) and the new state."""

    def auxiliary_loss(self, frames: Batch, precomputed: Batch) -> Tensor | None:
        """A supervised loss added to PPO's (None: none). ``frames`` are T·B flat frames."""
        return None


class MapMemory(Memory):
    """A memory whose step is a sequential update of its map, which yields a *view* (e.g. the
    egocentric crop), then a *read* of that view that the next update does not depend on.

    Replaying a sequence, the policy updates the map step by step and reads all T·B views in one
    batch: the same function and gradients (up to rounding) with one map CNN call instead of T,
    which made the learned-map agents' PPO updates several times slower (issue 30)."""

    @abstractmethod
    def advance(self, frame: Batch, state: State) -> tuple[Tensor, State]:
        """One step for B environments: the view (B, ...) to read and the new state."""

    @abstractmethod
    def read(self, views: Tensor, frames: Batch) -> Tensor:
        """``v_m`` (N, out_dim) of N views; ``frames`` are the same N frames (flat)."""

    def step(self, frame: Batch, query: Tensor, state: State) -> tuple[Tensor, State]:
        view, state = self.advance(frame, state)
        return self.read(view, frame), state
