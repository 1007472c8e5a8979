"""A habitat agent's run asks for the reference's oracle maps (``maps.convention =
"reference"``), and the leaderboard accepts it; the maps themselves are checked cell for cell
in ``tests/task/test_semantic_map.py``."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pytest

import multion_client.habitat_compat as habitat
from multion.api.local_server import LocalServer
from multion_client.run import RunEnv


class Recorder(habitat.Agent):
    """Moves ahead, keeps every semMap, and says FOUND after 4 steps."""

    def __init__(self) -> None:
        self.maps: list[np.ndarray] = []

    def reset(self) -> None:
        self.steps = 0

    def act(self, observations: dict[str, np.ndarray]) -> int:
        if "semMap" in observations:
            self.maps.append(observations["semMap"])
        self.steps += 1
        return 0 if self.steps == 4 else 1


@pytest.mark.parametrize("track", ["1-on-oracle", "1-on"])
def test_a_habitat_run_asks_for_the_reference_maps_on_oracle_tracks(
    track: str,
    server: LocalServer,
    new_team: Callable[[str], str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    token = new_team(f"sem-map-{np.random.default_rng().integers(10**9)}")
    for name, value in (
        ("MULTION_SERVER", server.url),
        ("MULTION_TOKEN", token),
        ("MULTION_TRACK", track),
        ("MULTION_PHASE", "minival"),
        ("MULTION_METHOD", "habitat agent"),
    ):
        monkeypatch.setenv(name, value)
    asked: list[Mapping[str, Any] | None] = []
    open_lanes = RunEnv.lanes

    def recording_lanes(*args: Any, **kwargs: Any) -> list[RunEnv]:  # a spy: passes all on
        asked.append(kwargs.get("maps"))
        return open_lanes(*args, **kwargs)

    monkeypatch.setattr(RunEnv, "lanes", recording_lanes)
    agent = Recorder()
    if track == "1-on":
        # no oracle maps on this track: nothing to configure (the server refuses maps there)
        habitat.Challenge().submit(agent)
        assert asked == [None]
        return
    habitat.Challenge().submit(agent)
    assert asked == [{"convention": "reference"}]
    assert agent.maps and all(m.shape == (50, 50, 2) for m in agent.maps)
