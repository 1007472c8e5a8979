"""A habitat-style MultiON challenge agent (written the habitat way, not with this project's
agents) plays leaderboard runs through ``multion_client.habitat_compat`` with one changed import."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import numpy as np
import pytest

import multion_client.habitat_compat as habitat
from multion.api.local_server import LocalServer
from multion_client.constants import GOAL_CATEGORIES, REFERENCE_CATEGORY_NAMES


class ForwardThenFound(habitat.Agent):
    """A 2022-challenge agent: walks ahead, turns when stuck, says FOUND at the end."""

    def __init__(self) -> None:
        self.episodes = 0
        self.seen: list[dict[str, np.ndarray]] = []
        self.steps = 0

    def reset(self) -> None:
        self.episodes += 1
        self.steps = 0

    def act(self, observations):
        self.seen.append(observations)
        self.steps += 1
        if self.steps == 8:
            return {"action": "FOUND"}
        return {"action": "MOVE_FORWARD"} if self.steps % 3 else 2  # TURN_LEFT as an int


class BatchedRandom(habitat.Agent):
    """The 2021 challenge's batched form: a list in, a list out, with not_done_masks."""

    def __init__(self) -> None:
        self.rng = np.random.default_rng(0)
        self.masks: list[np.ndarray] = []
        self.sizes: list[int] = []

    def reset(self) -> None:
        pass

    def act(self, observations, not_done_masks):
        self.masks.append(np.array(not_done_masks))
        self.sizes.append(len(observations))
        return [int(self.rng.choice([1, 1, 2, 3])) for _ in observations]


@pytest.fixture()
def play_settings(
    server: LocalServer, new_team: Callable[[str], str], monkeypatch: pytest.MonkeyPatch
) -> Iterator[None]:
    monkeypatch.setenv("MULTION_SERVER", server.url)
    monkeypatch.setenv(
        "MULTION_TOKEN", new_team(f"habitat-{np.random.default_rng().integers(1e9)}")
    )
    monkeypatch.setenv("MULTION_TRACK", "1-on")
    monkeypatch.setenv("MULTION_PHASE", "minival")
    monkeypatch.setenv("MULTION_METHOD", "habitat agent")
    yield


def test_habitat_agent_plays_a_run_unchanged(play_settings: None) -> None:
    agent = ForwardThenFound()
    results = habitat.Challenge().submit(agent)
    assert agent.episodes == 3  # the phase's three episodes, each after reset()
    assert results, "the run ended without results"
    first = agent.seen[0]
    assert set(first) == {"rgb", "depth", "multiobjectgoal", "gps", "compass"}
    assert first["rgb"].shape == (32, 32, 3) and first["rgb"].dtype == np.uint8
    assert (
        first["depth"].shape == (32, 32, 1)
        and 0.0 <= first["depth"].min() <= first["depth"].max() <= 1.0
    )
    goal = first["multiobjectgoal"]
    assert goal.dtype == np.int64 and goal.shape == (1,) and 0 <= goal[0] < 8
    assert first["gps"].tolist() == [0.0, 0.0] and first["compass"].shape == (1,)
    # after MOVE_FORWARD the agent is ahead of its start, not to its side; after a left turn
    # the compass is +30 degrees (habitat's compass turns counter-clockwise)
    second, third = agent.seen[1], agent.seen[2]
    assert second["gps"][0] in (0.0, pytest.approx(0.25, abs=1e-4))
    assert second["gps"][1] == pytest.approx(0.0, abs=1e-4)
    assert agent.seen[3]["compass"][0] == pytest.approx(math.radians(30), abs=1e-4)
    assert third["compass"][0] == pytest.approx(0.0, abs=1e-6)


def test_batched_agent_plays_over_lanes(
    play_settings: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MULTION_NUM_ENVS", "2")
    agent = BatchedRandom()
    habitat.Challenge().submit(agent)
    assert agent.sizes[0] == 2 and agent.masks[0].shape == (2, 1)
    assert (agent.masks[0] == 0).all()  # both episodes just started
    starts = sum(int((m == 0).sum()) for m in agent.masks)
    assert starts == 3  # every episode of the phase starts once, over the two lanes
    # the lane with no episode left keeps its place (lane k is position k) until the run ends
    assert set(agent.sizes) == {2} and agent.masks[-1].tolist() == [[1.0], [1.0]]


def test_oracle_track_gives_sem_map(play_settings: None, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MULTION_TRACK", "1-on-oracle")
    agent = ForwardThenFound()
    habitat.Challenge().submit(agent)
    sem = agent.seen[0]["semMap"]
    assert sem.ndim == 3 and sem.shape[0] == sem.shape[1] and sem.shape[2] == 2
    objects = set(np.unique(sem[..., 1]).tolist()) - {0}
    assert objects <= set(range(1, 9))


def test_conversions_follow_the_reference() -> None:
    depth = habitat.DepthRange({"min_depth": 0.5, "max_depth": 5.0, "normalize_depth": True})
    obs = {
        "goal": np.array(GOAL_CATEGORIES.index("magenta")),
        "gps": np.array([1.0, 2.0], dtype=np.float32),
        "compass": np.array([0.5], dtype=np.float32),
        "depth": np.array([[[0.0]], [[1.0]]], dtype=np.float32),
        "oracle_map": np.array([[[1, 0], [0, GOAL_CATEGORIES.index("cyan") + 1]]], dtype=np.uint8),
    }
    out = habitat.habitat_observations(obs, depth)
    assert REFERENCE_CATEGORY_NAMES[out["multiobjectgoal"][0]] == "pink"
    assert out["gps"].tolist() == [1.0, -2.0]  # [forward, right]
    assert out["depth"].ravel().tolist() == pytest.approx([0.05, 0.5])  # 0.5 m and 5 m of 10
    assert out["semMap"][0, 1, 1] == REFERENCE_CATEGORY_NAMES.index("cyan") + 1
    # goal sets the reference does not have keep their ids
    same = habitat.habitat_observations(obs, depth, habitat.IDENTITY)
    assert same["multiobjectgoal"][0] == GOAL_CATEGORIES.index("magenta")
    assert same["semMap"][0, 1, 1] == GOAL_CATEGORIES.index("cyan") + 1
    assert habitat.to_action({"action": "turn_right"}) == 3
    assert habitat.to_action(np.int64(1)) == 1
    with pytest.raises(ValueError, match="MOVE_FORWARD"):
        habitat.to_action("JUMP")
    with pytest.raises(ValueError, match="MOVE_FORWARD"):
        habitat.to_action({"act": 1})


def test_missing_settings_are_named(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in habitat.SETTINGS.values():
        monkeypatch.delenv(name, raising=False)
    with pytest.raises(ValueError, match="MULTION_SERVER, MULTION_TRACK, MULTION_PHASE"):
        habitat.Challenge()
    monkeypatch.setenv("MULTION_NUM_ENVS", "two")
    with pytest.raises(ValueError, match="MULTION_NUM_ENVS"):
        habitat.Challenge(server="http://x", track="t", phase="p", method="m")
