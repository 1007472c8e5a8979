"""``multion submit`` / ``leaderboard baselines``' progress bar (issue 42): on a phase that does
not say how episodes end (sealed, aggregate), the bar says so instead of ``last=None``."""

from __future__ import annotations

from typing import Any

import numpy as np

from multion_agents.cli_submit import play_run
from multion_agents.registry import agent_class


class SealedLane:
    """A run lane of two one-step episodes whose answers carry no end reason, as ``RunEnv``
    gives them on a sealed phase."""

    num_episodes = 2

    def __init__(self) -> None:
        self.episode = -1

    @property
    def run_done(self) -> bool:
        return self.episode >= self.num_episodes - 1

    def reset(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        self.episode += 1
        return {"goal": np.zeros(1, np.int64)}, {"episode": self.episode, "seq": 0}

    def step(self, action: int) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        info = {"episode": self.episode, "seq": 1, "end_reason": None}
        return {"goal": np.zeros(1, np.int64)}, 0.0, False, True, info


class RecordingBar:
    def __init__(self) -> None:
        self.postfixes: list[dict[str, Any]] = []

    def update(self, count: int) -> None:
        pass

    def set_postfix(self, **values: Any) -> None:
        self.postfixes.append(values)


def test_a_sealed_phase_shows_no_none_on_the_bar() -> None:
    bar = RecordingBar()
    play_run(SealedLane(), agent_class("random"), seed=0, bar=bar)  # type: ignore[arg-type]
    assert bar.postfixes == [{"last": "not shown"}] * 2
