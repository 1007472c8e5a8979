"""Where a FOUND head's gate should open (issue 51), read off episodes played at one gate.

At 1-ON, where a wrong FOUND ends the episode (``task.found_budget`` 0), the first FOUND ends
it either way: a success within the success distance, a wrong FOUND elsewhere. An episode
played with the gate at ``played`` therefore tells how it would have ended with any lower gate
``g``: until the first step whose head probability exceeds ``g`` every decision is the same
(the gate shut under both, the movements drawn alike), and at that step the lower gate calls
FOUND, which ends the episode. ``multion diagnose`` records each step's probability and whether
FOUND would succeed there, then reads every gate off the same episodes.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from multion_agents.learned.policy import FOUND_GATE

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
