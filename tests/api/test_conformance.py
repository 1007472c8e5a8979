"""One suite for the in-process ``MultiONEnv`` and ``RemoteEnv`` over a real local server.

Same seed and actions must give byte-identical observations and the same rewards, flags and
metrics; both must pass Gymnasium's env checker; and ``RemoteVectorEnv`` over two servers must
match ``SyncVectorEnv`` with SAME_STEP autoreset.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from multion.api.local_server import LocalServer
from multion.config.codec import session_config_from_dict
from multion.task.env import MultiONEnv
from multion_client import Client, RemoteEnv, RemoteVectorEnv

MakeEnv = Callable[[], gym.Env]


@pytest.fixture(scope="module")
def servers() -> Iterator[list[LocalServer]]:
    started = [LocalServer(workers=1), LocalServer(workers=1)]
    try:
        for server in started:
            server.launch()
        yield [server.wait_ready() for server in started]
    finally:
        for server in started:
            server.stop()


def local_factory(config: dict[str, Any]) -> MakeEnv:
    env_config, episodes = session_config_from_dict(config)
    return lambda: MultiONEnv(env_config, episodes)


@pytest.fixture(params=["local", "remote"])
def make_env(
    request: pytest.FixtureRequest, servers: list[LocalServer], small_config: dict[str, Any]
) -> Iterator[MakeEnv]:
    made: list[gym.Env] = []
    factory = (
        local_factory(small_config)
        if request.param == "local"
        else lambda: RemoteEnv(servers[0].url, small_config)
    )

    def make() -> gym.Env:
        made.append(factory())
        return made[-1]

    yield make
    for env in made:
        env.close()


def assert_same(a: Any, b: Any, where: str = "") -> None:
    """Exact equality; numpy values must match in type, dtype, shape and bytes."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), f"{where}: keys {list(a)} {list(b)}"
        for key in a:
            assert_same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert isinstance(b, np.ndarray) and a.shape == b.shape, where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, (np.ndarray, np.generic)):
        assert type(a) is type(b), f"{where}: {type(a)} vs {type(b)}"
        assert (a.dtype, a.shape) == (b.dtype, b.shape), where
        assert a.tobytes() == b.tobytes(), f"{where}: values differ"
    elif isinstance(a, (list, tuple)):  # msgpack has no tuples
        assert isinstance(b, (list, tuple)) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{i}]")
    else:
        assert type(a) is type(b) and a == b, f"{where}: {a!r} vs {b!r}"


def test_passes_gymnasium_env_checker(make_env: MakeEnv) -> None:
    check_env(make_env(), skip_render_check=True)


def test_remote_has_the_same_spaces(servers: list[LocalServer], small_config: dict) -> None:
    local, remote = local_factory(small_config)(), RemoteEnv(servers[0].url, small_config)
    try:
        assert remote.observation_space == local.observation_space
        assert remote.action_space == local.action_space
    finally:
        local.close()
        remote.close()


def test_same_trajectories(servers: list[LocalServer], small_config: dict) -> None:
    local, remote = local_factory(small_config)(), RemoteEnv(servers[0].url, small_config)
    episode = small_config["episodes"][2]
    resets: list[dict[str, Any]] = [
        {"seed": 5},
        {"options": {"episode_index": 1}},
        {"options": {"episode_id": "room-3"}},
        {"options": {"episode": episode}},
        {},
    ]
    rng = np.random.default_rng(0)
    try:
        for kwargs in resets:
            for env_out in zip(local.reset(**kwargs), remote.reset(**kwargs), strict=True):
                assert_same(*env_out, "reset")
            for step in range(40):
                action = int(rng.choice(4, p=[0.05, 0.55, 0.2, 0.2]))
                out_local, out_remote = local.step(action), remote.step(action)
                assert_same(out_local, out_remote, f"step {step}")
                if out_local[2] or out_local[3]:
                    break
        assert remote.metrics() == local.metrics()
    finally:
        local.close()
        remote.close()


def test_same_errors(make_env: MakeEnv) -> None:
    env = make_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="illegal action"):
        env.step(9)
    _, _, terminated, _, _ = env.step(0)  # FOUND far from the goal ends the episode
    assert terminated
    with pytest.raises(RuntimeError, match="reset"):
        env.step(1)


def test_vector_env_over_two_servers_matches_sync_vector_env(
    servers: list[LocalServer], small_config: dict
) -> None:
    remote = RemoteVectorEnv([s.url for s in servers], [2, 1], small_config)
    local = SyncVectorEnv([local_factory(small_config)] * 3, autoreset_mode=AutoresetMode.SAME_STEP)
    rng = np.random.default_rng(1)
    ended = 0
    try:
        assert remote.observation_space == local.observation_space
        assert remote.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
        assert_same(local.reset(seed=3), remote.reset(seed=3), "reset")
        for step in range(45):
            actions = rng.choice(4, size=3, p=[0.1, 0.5, 0.2, 0.2])
            out_local, out_remote = local.step(actions), remote.step(actions)
            assert_same(out_local, out_remote, f"step {step}")
            ended += int(np.sum(out_local[2] | out_local[3]))
        assert ended >= 2  # auto-resets (and their final_obs / final_info) were compared
    finally:
        local.close()
        remote.close()


def test_the_client_reads_the_sessions_renderer(
    servers: list[LocalServer], small_config: dict[str, Any]
) -> None:
    """The create answer's header names the renderer; the client puts it in SessionInfo."""
    with Client(servers[0].url) as client:
        info = client.create_session(small_config)
        client.close_session(info.session_id)
    assert info.renderer == "tiny"  # the config's default renderer, which auto does not change
