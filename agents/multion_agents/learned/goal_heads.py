"""Auxiliary goal heads on the recurrent state (``--goal-heads``; Marza et al., "Teaching Agents
how to Map", IROS 2022, winners of the MultiON 2021 challenge).

Three linear heads read the GRU's output and are trained from ground truth, then dropped when
the policy acts in an evaluation:

* **seen**: has the current goal been in view this episode (2 classes);
* **direction**: its bearing from the agent, 12 bins of 30°;
* **distance**: its straight-line distance, 35 bins of 0.8 m (one per map cell).

Cross-entropy on each; direction and distance only on the steps where the goal has been seen
(PierreMarza/teaching_agents_how_to_map ``habitat_baselines/rl/ppo/policy.py`` l. 386-400 for
the heads, l. 611-640 for the losses; each weighted 0.25, ``ppo_multinav.yaml`` l. 48-50).

Theirs label from the oracle map under a fog of war (``aux_losses_utils.py``: the mean of the
goal's cells on a 50-cell crop); ours from the ``goal_vector`` training sensor, which the env
computes from the same facts without the map: seen within 6 m in the camera's field of view,
the goal's bearing, its distance. Their direction bins start at 15° off ahead; ours are
centred on ahead (bin 0 is ahead ± 15°, counter-clockwise from there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor, nn

GOAL_VECTOR = "goal_vector"
"""The training sensor the targets come from: (seen, bearing in radians, distance in metres)."""
DIRECTION_BINS = 12
DISTANCE_BINS = 35
DISTANCE_BIN_METRES = 0.8
"""One oracle-map cell (``maps.cell_size``'s default): Marza et al. bin distances by cells."""


@dataclass(frozen=True)
class GoalTargets:
    """Per frame: ``seen`` (0/1), ``direction`` (0-11) and ``distance`` (0-34) class indices."""

    seen: Tensor
    direction: Tensor
    distance: Tensor


def goal_seen(vector: Tensor) -> Tensor:
    """Whether the current goal has been in view this episode, from ``goal_vector``
    observations (..., 3): their first value, 0 or 1."""
    return vector[..., 0] > 0.5


def goal_targets(vector: Tensor) -> GoalTargets:
    """The three heads' class labels of ``goal_vector`` observations (N, 3)."""
    vector = vector.float()
    degrees = torch.rad2deg(vector[:, 1])
    half_bin = 180.0 / DIRECTION_BINS
    direction = torch.floor(torch.remainder(degrees + half_bin, 360.0) / (2 * half_bin))
    distance = torch.floor(vector[:, 2] / DISTANCE_BIN_METRES)
    return GoalTargets(
        seen=goal_seen(vector).long(),
        direction=direction.long().clamp(0, DIRECTION_BINS - 1),
        distance=distance.long().clamp(0, DISTANCE_BINS - 1),
    )


@dataclass(frozen=True)
class GoalLosses:
    """The heads' cross-entropies (direction and distance 0 where no frame has seen its goal)
    and the share of frames whose goal has been seen."""

    seen: Tensor
    direction: Tensor
    distance: Tensor
    seen_share: Tensor

    @property
    def total(self) -> Tensor:
        return self.seen + self.direction + self.distance


class GoalHeads(nn.Module):
    """The three linear heads on a GRU output of ``hidden_size`` units."""

    def __init__(self, hidden_size: int) -> None:
        super().__init__()
        self.seen = _head(hidden_size, 2)
        self.direction = _head(hidden_size, DIRECTION_BINS)
        self.distance = _head(hidden_size, DISTANCE_BINS)

    def losses(self, core: Tensor, vector: Tensor) -> GoalLosses:
        """The losses of GRU outputs ``core`` (N, H) against ``goal_vector`` (N, 3)."""
        targets = goal_targets(vector)
        ce = nn.functional.cross_entropy
        seen_loss = ce(self.seen(core), targets.seen)
        where = targets.seen.bool()
        zero = core.new_zeros(())
        if where.any():
            seen_core = core[where]
            direction = ce(self.direction(seen_core), targets.direction[where])
            distance = ce(self.distance(seen_core), targets.distance[where])
        else:
            direction = distance = zero
        return GoalLosses(seen_loss, direction, distance, where.float().mean())


def _head(inputs: int, classes: int) -> nn.Linear:
    layer = nn.Linear(inputs, classes)
    nn.init.orthogonal_(layer.weight)  # as theirs (policy.py l. 387-388)
    nn.init.constant_(layer.bias, 0.0)
    return layer


def direction_bin_centre(index: int) -> float:
    """The bearing (radians) at the centre of direction bin ``index`` (for tests and plots)."""
    return math.remainder(index * 2 * math.pi / DIRECTION_BINS, 2 * math.pi)
