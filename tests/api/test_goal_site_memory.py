"""A worker reserves what its envs share once, however many envs use it: the goal-site field
cache of train envs (issue 44, :mod:`multion.task.goal_sites`) and the OpenGL context of gl
envs (issue 43, :mod:`multion.sim.gl`)."""

from __future__ import annotations

import os
from typing import Any

import pytest
from fastapi.testclient import TestClient

from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion.api.workers import WORKER_RESERVED_BYTES
from multion.config.codec import session_config_from_dict
from multion.sim.gl.context import gl_unavailable_reason_in_child
from multion.task.memory import estimate_env_bytes, goal_sites_bytes, mib, process_share
from multion_client.protocol import CONTENT_TYPE, decode, encode, session_path

TRAIN = {
    "split": "train",
    "camera": {"width": 32, "height": 32},
    "sensors": ["rgb", "depth", "goal"],
    "episodes_per_scene": 2,
}
ENVS = 16


def call(api: TestClient, method: str, path: str, body: Any = None) -> tuple[int, Any]:
    content = None if body is None else encode(body)
    response = api.request(method, path, content=content, headers={"content-type": CONTENT_TYPE})
    assert response.status_code < 500, response.content
    return response.status_code, decode(response.content)


def reserved_mib(api: TestClient) -> int:
    return int(call(api, "GET", "/v1/health")[1]["workers"][0]["reserved_mib"])


def create(api: TestClient, config: dict[str, Any], num_envs: int) -> tuple[int, Any]:
    return call(api, "POST", "/v1/sessions", {"config": config, "num_envs": num_envs})


def test_sixteen_train_envs_reserve_the_site_cache_once_on_their_worker() -> None:
    config = session_config_from_dict(TRAIN)[0]
    env_bytes, cache_bytes = estimate_env_bytes(config), goal_sites_bytes(config)
    assert cache_bytes == 800 * 2**20  # the default task.goal_site_cache_mib
    # room for 18 envs and one cache: counted per env, 16 would need 16 caches
    worker_mb = mib(18 * env_bytes + cache_bytes + WORKER_RESERVED_BYTES) + 16
    capacity = worker_mb * 2**20 - WORKER_RESERVED_BYTES
    assert ENVS * (env_bytes + cache_bytes) > capacity
    settings = ServerSettings(workers=1, worker_memory_mb=worker_mb, max_envs_per_session=64)
    with TestClient(create_app(settings), raise_server_exceptions=False) as api:
        status, body = create(api, TRAIN, ENVS)
        assert status == 201, body
        first = body["session_id"]
        assert reserved_mib(api) == mib(ENVS * env_bytes + cache_bytes)
        # the envs really run under the worker's address-space limit: one house, one cache
        status, _ = call(api, "POST", session_path(first, "reset"), {"seeds": [3] * ENVS})
        assert status == 200

        # another train session on the worker reserves its envs alone
        status, body = create(api, TRAIN, 2)
        assert status == 201, body
        assert reserved_mib(api) == mib((ENVS + 2) * env_bytes + cache_bytes)
        status, refused = create(api, TRAIN, 1)
        assert status == 429 and refused["error"]["code"] == "memory_budget_exceeded"
        assert (
            f"plus {mib(cache_bytes)} MiB for the goal-site field cache "
            "(task.goal_site_cache_mib) once per worker" in refused["error"]["message"]
        )
        call(api, "DELETE", session_path(body["session_id"]))

        # a larger budget on the same worker reserves only what the cache lacks of it
        larger = {**TRAIN, "task": {"goal_site_cache_mib": 850}}
        status, body = create(api, larger, 1)
        assert status == 201, body
        assert reserved_mib(api) == mib((ENVS + 1) * env_bytes + 850 * 2**20)
        call(api, "DELETE", session_path(body["session_id"]))
        assert reserved_mib(api) == mib(ENVS * env_bytes + cache_bytes)

        call(api, "DELETE", session_path(first))
        assert reserved_mib(api) == 0  # the cache went with the last session drawing from it


def test_a_cache_no_worker_can_hold_is_refused_naming_its_field() -> None:
    settings = ServerSettings(workers=1, worker_memory_mb=2048)
    with TestClient(create_app(settings), raise_server_exceptions=False) as api:
        config = {**TRAIN, "task": {"goal_site_cache_mib": 4096}}
        status, body = create(api, config, 1)
        assert status == 422 and body["error"]["code"] == "invalid_config"
        message = body["error"]["message"]
        assert (
            "plus 4096 MiB for the goal-site field cache (task.goal_site_cache_mib) of its worker"
            in message
        )
        assert "a smaller task.goal_site_cache_mib" in message
        assert reserved_mib(api) == 0


def test_plain_sessions_count_the_cache_once_in_their_share() -> None:
    config = session_config_from_dict(TRAIN)[0]
    env_bytes, cache_bytes = estimate_env_bytes(config), goal_sites_bytes(config)
    worker_mb = mib(8 * env_bytes + cache_bytes + WORKER_RESERVED_BYTES)
    capacity = worker_mb * 2**20 - WORKER_RESERVED_BYTES
    # plain sessions may take room for 4.5 envs and the cache; the rest is kept for runs
    reserve = 1 - (4.5 * env_bytes + cache_bytes) / capacity
    settings = ServerSettings(workers=1, worker_memory_mb=worker_mb, sessions_per_client=8)
    with TestClient(create_app(settings), raise_server_exceptions=False) as api:
        api.app.state.registry.run_reserve = reserve  # as a server running a challenge sets it
        opened = []
        for _ in range(2):
            status, body = create(api, TRAIN, 2)
            assert status == 201, body
            opened.append(body["session_id"])
        assert reserved_mib(api) == mib(4 * env_bytes + cache_bytes)
        status, body = create(api, TRAIN, 1)
        assert status == 429 and "the rest is kept for runs" in body["error"]["message"]
        for session_id in opened:
            call(api, "DELETE", session_path(session_id))
        assert reserved_mib(api) == 0


GL = {"camera": {"width": 32, "height": 32, "renderer": "gl"}, "sensors": ["rgb", "depth", "goal"]}
GL_ENVS = 12


def test_gl_envs_reserve_their_worker_s_context_once() -> None:
    """12 gl envs fit a worker with room for one context and 12 envs' buffers; charged a
    context each (the old charge), they would need 12. A train session beside them adds its
    cache but no second context, and the context goes with the last gl env."""
    reason = gl_unavailable_reason_in_child()
    if reason is not None:
        if os.environ.get("MULTION_REQUIRE_EGL") == "1":
            pytest.fail(f"MULTION_REQUIRE_EGL=1 but {reason}")
        pytest.skip(reason)
    gl_config = session_config_from_dict(GL)[0]
    gl_env, context = estimate_env_bytes(gl_config), process_share(gl_config).gl_context
    train = session_config_from_dict(TRAIN)[0]
    train_env, cache = estimate_env_bytes(train), goal_sites_bytes(train)
    room = GL_ENVS * gl_env + context + train_env + cache
    worker_mb = mib(room + WORKER_RESERVED_BYTES) + 16
    assert GL_ENVS * (gl_env + context) > worker_mb * 2**20  # a context per env: refused
    settings = ServerSettings(workers=1, worker_memory_mb=worker_mb, max_envs_per_session=64)
    with TestClient(create_app(settings), raise_server_exceptions=False) as api:
        status, body = create(api, GL, GL_ENVS)
        assert status == 201, body
        gl_session = body["session_id"]
        assert reserved_mib(api) == mib(GL_ENVS * gl_env + context)
        # the envs render under the worker's address-space limit: one context for all
        status, _ = call(api, "POST", session_path(gl_session, "reset"), {"seeds": [5] * GL_ENVS})
        assert status == 200

        status, body = create(api, TRAIN, 1)
        assert status == 201, body
        assert reserved_mib(api) == mib(GL_ENVS * gl_env + context + train_env + cache)
        call(api, "DELETE", session_path(gl_session))
        assert reserved_mib(api) == mib(train_env + cache)
