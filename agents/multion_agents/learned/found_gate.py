"""A FOUND head's gate (issue 51): how it masks the actor (:func:`gated_logits`), and where it
should open, read off episodes played at one gate.

At 1-ON, where a wrong FOUND ends the episode (``task.found_budget`` 0), the first FOUND ends
it either way: a success within the success distance, a wrong FOUND elsewhere. An episode
played with the gate at ``played`` therefore tells how it would have ended with any lower gate
``g``: until the first step whose head probability exceeds ``g`` every decision is the same
(the gate shut under both, the movements drawn alike), and at that step the lower gate calls
FOUND, which ends the episode. ``multion diagnose`` records each step's probability and whether
FOUND would succeed there, then reads every gate off the same episodes.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from multion_client.constants import Action

FOUND_HEAD_PRIOR = 0.02
"""The untrained FOUND head's probability (its bias): well under the gate's 0.5, so an untrained
policy never calls FOUND."""
FOUND_GATE = 0.5
"""The FOUND head's probability above which the policy calls FOUND, unless told otherwise
(``RecurrentPolicy.found_gate``; ``multion eval --found-gate``)."""
FOUND = int(Action.FOUND)
SUCCESS = "success"
WRONG_FOUND = "wrong_found"


@dataclass(frozen=True)
class GateTrace:
    """One played episode, step by step."""

    probability: np.ndarray
    """(steps,) the FOUND head's probability at each step."""
    in_reach: np.ndarray
    """(steps,) whether FOUND would have succeeded at that step."""
    in_view: np.ndarray
    """(steps,) whether the frame showed the goal (``goal_mask``)."""
    ending: str
    """How the episode ended (``end_reason``: success, wrong_found, max_steps)."""


def ending_at_gate(trace: GateTrace, gate: float, played: float = FOUND_GATE) -> str:
    """How the episode of ``trace`` (played with the gate at ``played``) would have ended with
    the gate at ``gate`` (≤ ``played``: a higher gate would have gone on past its FOUND)."""
    if not 0.0 < gate <= played:
        raise ValueError(f"a gate must be in (0, {played:g}] (the gate played), got {gate!r}")
    above = np.flatnonzero(trace.probability > gate)
    if above.size == 0:
        return trace.ending
    return SUCCESS if trace.in_reach[above[0]] else WRONG_FOUND


def gate_endings(
    traces: Sequence[GateTrace], gates: Sequence[float], played: float = FOUND_GATE
) -> dict[float, dict[str, int]]:
    """Per gate, how many of ``traces``' episodes would have ended each way."""
    return {
        gate: dict(Counter(ending_at_gate(trace, gate, played) for trace in traces))
        for gate in gates
    }


def parse_gates(text: str) -> tuple[float, ...]:
    """``"0.1,0.3"`` → (0.1, 0.3); a ValueError naming ``--gates`` for anything else."""
    try:
        gates = tuple(sorted({float(item) for item in text.split(",") if item.strip()}))
    except ValueError:
        raise ValueError(f"--gates takes probabilities separated by commas, got {text!r}") from None
    if not gates or not all(0.0 < gate <= FOUND_GATE for gate in gates):
        raise ValueError(f"--gates must be in (0, {FOUND_GATE:g}] (the gate played), got {text!r}")
    return gates


def gate_logit(probability: float) -> float:
    """The FOUND head's logit at which a gate of ``probability`` opens (the logit of that
    probability)."""
    if not 0.0 < probability < 1.0:
        raise ValueError(f"found_gate must be in (0, 1), got {probability!r}")
    return math.log(probability / (1.0 - probability))


def gated_logits(actor_logits: Tensor, fired: Tensor) -> Tensor:
    """The action logits (..., A) of a policy whose FOUND a head decides: where ``fired`` (...)
    FOUND alone (probability 1), elsewhere the actor's movements with FOUND impossible. A
    replay that gates as the acting did gives a FOUND step log-probability 0 (PPO's ratio 1:
    the actor is not taught by it) and a movement the actor's own renormalised log-probability."""
    lowest = torch.finfo(actor_logits.dtype).min
    found = torch.zeros_like(actor_logits, dtype=torch.bool)
    found[..., FOUND] = True
    only_found = torch.full_like(actor_logits, lowest).masked_fill(found, 0.0)
    moves = actor_logits.masked_fill(found, lowest)
    return torch.where(fired.unsqueeze(-1), only_found, moves)
