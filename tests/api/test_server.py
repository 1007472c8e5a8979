"""The HTTP server in-process (TestClient): routes, every error case, reaping, worker failure."""

from __future__ import annotations

import contextlib
import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

import multion
from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion.config.codec import ConfigError, env_config_from_dict, env_config_to_dict
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig
from multion.task.spaces import build_observation_space
from multion_client.protocol import (
    CONTENT_TYPE,
    SessionInfo,
    decode,
    encode,
    session_path,
    space_from_wire,
)
from waiting import wait_until

SETTINGS = ServerSettings(
    workers=2,
    max_sessions=4,
    max_envs_per_session=4,
    max_envs_total=6,
    max_request_bytes=100_000,
    idle_timeout_s=600,
)


@pytest.fixture(scope="module")
def api() -> Iterator[TestClient]:
    with TestClient(create_app(SETTINGS), raise_server_exceptions=False) as client:
        yield client


def call(
    api: TestClient, method: str, path: str, body: Any = None, raw: bytes | None = None
) -> tuple[int, Any]:
    content = raw if raw is not None else None if body is None else encode(body)
    response = api.request(method, path, content=content, headers={"content-type": CONTENT_TYPE})
    assert response.headers["content-type"] == CONTENT_TYPE
    assert response.status_code < 500 or response.status_code == 503, response.content
    return response.status_code, decode(response.content)


def error_of(answer: tuple[int, Any]) -> tuple[int, str, str]:
    status, body = answer
    return status, body["error"]["code"], body["error"]["message"]


@contextlib.contextmanager
def session(
    api: TestClient, config: dict[str, Any], num_envs: int = 1, auto_reset: bool = False
) -> Iterator[str]:
    status, body = call(
        api,
        "POST",
        "/v1/sessions",
        {"config": config, "num_envs": num_envs, "auto_reset": auto_reset},
    )
    assert status == 201, body
    try:
        yield body["session_id"]
    finally:
        call(api, "DELETE", session_path(body["session_id"]))


def test_health_spec_and_docs(api: TestClient) -> None:
    status, health = call(api, "GET", "/v1/health")
    assert status == 200 and health["status"] == "ok" and health["api_version"] == "v1"
    assert len(health["workers"]) == 2 and all(w["alive"] for w in health["workers"])
    status, spec = call(api, "GET", "/v1/spec")
    assert status == 200
    assert spec["actions"] == {"FOUND": 0, "MOVE_FORWARD": 1, "TURN_LEFT": 2, "TURN_RIGHT": 3}
    assert "rgb" in spec["sensors"] and spec["defaults"]["camera"]["width"] == 256
    assert spec["renderer"]["default"] == spec["defaults"]["camera"]["renderer"] == "tiny"
    assert spec["renderer"]["auto"] in ("tiny", "gl")
    # auto falls back to tiny exactly where gl cannot run, and then says why
    assert (spec["renderer"]["auto"] == "tiny") == (spec["renderer"]["gl_unavailable"] is not None)
    assert space_from_wire(spec["observation_space"]) == build_observation_space(EnvConfig())
    assert spec["limits"]["max_sessions"] == 4
    # the defaults that decide the map vs no-map comparison cite the reference code (issue 31)
    assert (
        spec["defaults"]["maps"]["ego_size"] == 50 and "env.py" in spec["sources"]["maps.ego_size"]
    )
    assert spec["defaults"]["camera"]["max_depth"] == 10.0
    assert "default.py line 304" in spec["sources"]["camera.max_depth"]
    assert spec["goal_sets"]["colours"] == spec["goal_categories"]
    assert spec["goal_sets"]["shapes"][0] == "cone" and len(spec["goal_sets"]["shapes"]) == 8
    for name in spec["sources"]:  # every cited field is a config field
        section, key = name.split(".")
        assert key in spec["defaults"][section], name
    paths = api.get("/openapi.json").json()["paths"]
    for path, method in [
        ("/v1/health", "get"),
        ("/v1/spec", "get"),
        ("/v1/sessions", "post"),
        ("/v1/sessions/{session_id}/reset", "post"),
        ("/v1/sessions/{session_id}/step", "post"),
        ("/v1/sessions/{session_id}/observe", "get"),
        ("/v1/sessions/{session_id}", "delete"),
    ]:
        assert paths[path][method]["summary"] and paths[path][method]["description"]


def test_session_lifecycle(api: TestClient, small_config: dict[str, Any]) -> None:
    with session(api, small_config) as sid:
        status, body = call(api, "POST", session_path(sid, "reset"), {"seeds": [3]})
        assert status == 200
        obs = body["observations"][0]
        assert obs["rgb"].shape == (32, 32, 3) and obs["rgb"].dtype == np.uint8
        assert obs["depth"].shape == (32, 32, 1) and obs["depth"].dtype == np.float32
        assert isinstance(obs["goal"], np.int64)
        assert body["infos"][0]["scene_id"] == "room-6x4"
        status, body = call(api, "POST", session_path(sid, "step"), {"actions": [2]})
        assert status == 200 and body["terminated"] == [False] and body["truncated"] == [False]
        assert isinstance(body["rewards"][0], float)
        status, seen = call(api, "GET", session_path(sid, "observe"))
        assert status == 200
        assert seen["observations"][0]["rgb"].tobytes() == body["observations"][0]["rgb"].tobytes()
        assert seen["infos"] == body["infos"]
        assert call(api, "DELETE", session_path(sid)) == (200, {"closed": sid})
        assert error_of(call(api, "GET", session_path(sid, "observe")))[:2] == (
            404,
            "session_not_found",
        )


def test_session_info_has_the_env_spaces(api: TestClient, small_config: dict[str, Any]) -> None:
    status, body = call(api, "POST", "/v1/sessions", {"config": small_config})
    info = SessionInfo.from_wire(body)
    try:
        config = EnvConfig(camera=CameraConfig(width=32, height=32))
        assert status == 201 and info.observation_space == build_observation_space(config)
        assert info.action_space.n == 4 and info.num_envs == 1 and not info.auto_reset
    finally:
        call(api, "DELETE", session_path(info.session_id))


def test_envs_of_a_session_are_spread_over_workers(
    api: TestClient, small_config: dict[str, Any]
) -> None:
    with session(api, small_config, num_envs=4) as sid:
        _, health = call(api, "GET", "/v1/health")
        assert sorted(w["envs"] for w in health["workers"]) == [2, 2]
        options = [{"episode_index": i} for i in (2, 0, 1, 3)]
        status, body = call(api, "POST", session_path(sid, "reset"), {"options": options})
        assert status == 200
        assert [i["episode_id"] for i in body["infos"]] == ["room-2", "room-0", "room-1", "room-3"]
        status, body = call(api, "POST", session_path(sid, "step"), {"actions": [1, 2, 3, 2]})
        assert status == 200 and len(body["observations"]) == 4 and len(body["rewards"]) == 4


@pytest.mark.parametrize(
    ("method", "verb", "body"),
    [("POST", "reset", {}), ("POST", "step", {"actions": [1]}), ("GET", "observe", None),
     ("DELETE", None, None)],
)  # fmt: skip
def test_unknown_session(api: TestClient, method: str, verb: str | None, body: Any) -> None:
    status, code, message = error_of(call(api, method, session_path("no-such-id", verb), body))
    assert (status, code) == (404, "session_not_found") and "no-such-id" in message


def test_bad_actions(api: TestClient, small_config: dict[str, Any]) -> None:
    with session(api, small_config, num_envs=2) as sid:
        call(api, "POST", session_path(sid, "reset"), {})
        for bad in (7, -1, 1.5, 1.0, True, np.float32(1.0), "1", None, [1], np.array([1])):
            status, code, message = error_of(
                call(api, "POST", session_path(sid, "step"), {"actions": [1, bad]})
            )
            assert (status, code) == (400, "invalid_action") and "environment 1" in message
        for actions in ([1], [1, 2, 3], []):
            status, code, message = error_of(
                call(api, "POST", session_path(sid, "step"), {"actions": actions})
            )
            assert (status, code) == (400, "bad_request") and "expected 2 action(s)" in message
        # nothing was stepped by the refused requests
        _, body = call(api, "GET", session_path(sid, "observe"))
        assert body["infos"][0]["metrics"]["steps"] == 0
        # numpy integers and integer arrays are actions
        for actions in ([np.int64(2), np.uint8(3)], np.array([2, 3], dtype=np.int32)):
            status, body = call(api, "POST", session_path(sid, "step"), {"actions": actions})
            assert status == 200 and len(body["rewards"]) == 2


def test_strict_reset_seeds_and_options(api: TestClient, small_config: dict[str, Any]) -> None:
    with session(api, small_config) as sid:
        for seeds, match in (([-1], "seeds[0] = -1"), ([2**63], "seeds[0] = 9223372036854775808")):
            status, code, message = error_of(
                call(api, "POST", session_path(sid, "reset"), {"seeds": seeds})
            )
            assert (status, code) == (400, "malformed_message") and match in message
            assert "[0, 9223372036854775807]" in message
        for options, match in (
            ({"episode_idx": 0}, "unknown reset option(s) ['episode_idx']; reset options are"),
            ({"episode_index": "0"}, "'episode_index' must be an int"),
            ({"episode_index": True}, "'episode_index' must be an int"),
            ({"episode_index": 0, "episode_id": "x"}, "at most one of the reset options"),
        ):
            status, code, message = error_of(
                call(api, "POST", session_path(sid, "reset"), {"options": [options]})
            )
            assert (status, code) == (400, "bad_request") and match in message
            assert message.startswith("environment 0: ")
        assert call(api, "POST", session_path(sid, "reset"), {"seeds": [2**63 - 1]})[0] == 200


@pytest.mark.parametrize(
    ("raw", "match"),
    [
        (b"\xc1", "not valid msgpack"),
        (b"", "needs a msgpack body"),
        (encode([1, 2]), "expected a map"),
        (encode({"action": [1]}), "unknown field"),
        (encode({"actions": "1"}), "must be a list"),
    ],
)
def test_malformed_bodies(
    api: TestClient, small_config: dict[str, Any], raw: bytes, match: str
) -> None:
    with session(api, small_config) as sid:
        status, code, message = error_of(call(api, "POST", session_path(sid, "step"), raw=raw))
        assert (status, code) == (400, "malformed_message") and match in message


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"camera": {"widht": 64}}, "unknown field 'camera.widht'"),
        ({"camera": {"width": "64"}}, "field 'camera.width' must be an int"),
        ({"sensors": ["sonar"]}, "unknown sensor"),
        ({"task": {"num_goals": 3}}, "has 2 goals but task.num_goals is 3"),
        ({"episodes": [{"scene_id": "room-6x4"}]}, "missing field 'episodes[0].episode_id'"),
        ({"split": "nowhere"}, "split = 'nowhere' is not allowed"),
        ({"split": "../../tmp/x"}, "allowed one of 'train', 'val', 'test'"),
        ({"camera": {"width": 0}}, "camera.width = 0 is out of range: allowed an integer in [1,"),
        (
            {"maps": {"ego_size": 100001}},
            "maps.ego_size = 100001 is out of range: allowed an integer in [1, 1001]",
        ),
        ({"navgrid": {"cell_size": 1e-6}}, "navgrid.cell_size = 1e-06 is out of range"),
        ({"camera": {"min_depth": 10.0}}, "camera.min_depth (10.0) must be below camera.max_depth"),
        # found by the worker; the message names the task, not the server's directories
        ({"episodes": None, "task": {"num_goals": 5}, "split": "test"}, "no packaged 5-on test"),
    ],
)
def test_bad_configs(
    api: TestClient, small_config: dict[str, Any], change: dict[str, Any], match: str
) -> None:
    config = {**small_config, **change}
    if config.get("episodes") is None:
        config.pop("episodes")
    status, code, message = error_of(call(api, "POST", "/v1/sessions", {"config": config}))
    assert (status, code) == (422, "invalid_config") and match in message
    assert str(Path(multion.__file__).parent) not in message  # no server paths
    assert call(api, "GET", "/v1/health")[1]["sessions"] == 0


def test_bad_episode_options(api: TestClient, small_config: dict[str, Any]) -> None:
    with session(api, small_config) as sid:
        for options in ({"episode_index": 99}, {"episode_id": "nope"}, {"episode": {"x": 1}}):
            status, code, message = error_of(
                call(api, "POST", session_path(sid, "reset"), {"options": [options]})
            )
            assert (status, code) == (422, "invalid_episode") and "environment 0" in message
        status, code, _ = error_of(call(api, "POST", session_path(sid, "reset"), {"seeds": [1, 2]}))
        assert (status, code) == (400, "bad_request")
        assert call(api, "POST", session_path(sid, "reset"), {"seeds": [0]})[0] == 200


def test_episode_over_without_auto_reset(api: TestClient, small_config: dict[str, Any]) -> None:
    with session(api, small_config) as sid:
        assert error_of(call(api, "GET", session_path(sid, "observe")))[:2] == (409, "not_reset")
        assert error_of(call(api, "POST", session_path(sid, "step"), {"actions": [1]}))[:2] == (
            409,
            "episode_over",
        )
        call(api, "POST", session_path(sid, "reset"), {})
        # FOUND at the start is wrong (goals are ≥ 2 m away): the episode ends at once
        status, body = call(api, "POST", session_path(sid, "step"), {"actions": [0]})
        assert status == 200 and body["terminated"] == [True]
        assert body["infos"][0]["metrics"]["end_reason"] == "wrong_found"
        status, code, message = error_of(
            call(api, "POST", session_path(sid, "step"), {"actions": [1]})
        )
        assert (status, code) == (409, "episode_over") and "reset" in message
        assert call(api, "GET", session_path(sid, "observe"))[0] == 200
        call(api, "POST", session_path(sid, "reset"), {})
        assert call(api, "POST", session_path(sid, "step"), {"actions": [1]})[0] == 200


def test_auto_reset_same_step(api: TestClient, small_config: dict[str, Any]) -> None:
    with session(api, small_config, num_envs=2, auto_reset=True) as sid:
        _, first = call(api, "POST", session_path(sid, "reset"), {"seeds": [0, 1]})
        status, body = call(api, "POST", session_path(sid, "step"), {"actions": [0, 2]})
        assert status == 200 and body["terminated"] == [True, False]
        ended, going = body["infos"]
        assert "final_obs" not in going
        assert ended["final_info"]["metrics"]["end_reason"] == "wrong_found"
        assert ended["final_info"]["episode_id"] == first["infos"][0]["episode_id"]
        assert ended["episode_id"] != first["infos"][0]["episode_id"]  # the next episode
        assert ended["metrics"]["steps"] == 0
        assert ended["final_obs"]["rgb"].shape == (32, 32, 3)
        # the returned observation is the new episode's first one; stepping goes on
        assert call(api, "POST", session_path(sid, "step"), {"actions": [1, 1]})[0] == 200


def test_limits(api: TestClient, small_config: dict[str, Any]) -> None:
    status, code, message = error_of(
        call(api, "POST", "/v1/sessions", {"config": small_config, "num_envs": 5})
    )
    assert (status, code) == (429, "too_many_envs") and "per session" in message
    with session(api, small_config, 4), session(api, small_config, 2):
        status, code, _ = error_of(call(api, "POST", "/v1/sessions", {"config": small_config}))
        assert (status, code) == (429, "too_many_envs")
    with contextlib.ExitStack() as stack:
        for _ in range(4):
            stack.enter_context(session(api, small_config))
        status, code, message = error_of(
            call(api, "POST", "/v1/sessions", {"config": small_config})
        )
        assert (status, code) == (429, "too_many_sessions") and "4" in message
    assert call(api, "GET", "/v1/health")[1]["envs"] == 0


def test_request_too_large(api: TestClient, small_config: dict[str, Any]) -> None:
    config = {**small_config, "padding": "x" * 200_000}
    status, code, message = error_of(call(api, "POST", "/v1/sessions", {"config": config}))
    assert (status, code) == (413, "request_too_large") and "100000" in message


def test_unknown_routes_and_methods(api: TestClient) -> None:
    assert error_of(call(api, "GET", "/v1/nothing"))[:2] == (404, "not_found")
    assert error_of(call(api, "GET", "/v2/health"))[:2] == (404, "not_found")
    assert error_of(call(api, "PUT", "/v1/sessions"))[:2] == (405, "method_not_allowed")


def test_killed_worker_is_replaced(api: TestClient, small_config: dict[str, Any]) -> None:
    health = lambda: call(api, "GET", "/v1/health")[1]  # noqa: E731
    replaced = health()["workers_replaced"]
    with session(api, small_config) as doomed:
        victim = next(w for w in health()["workers"] if w["envs"] == 1)
        with session(api, small_config) as survivor:
            for sid in (doomed, survivor):
                call(api, "POST", session_path(sid, "reset"), {})
            os.kill(victim["pid"], signal.SIGKILL)
            wait_until(
                lambda: health()["workers_replaced"] == replaced + 1, 30, 0.05, "a new worker"
            )
            status, code, message = error_of(
                call(api, "POST", session_path(doomed, "step"), {"actions": [1]})
            )
            assert (status, code) == (503, "worker_failed") and "died" in message
            assert (
                error_of(call(api, "POST", session_path(doomed, "reset"), {}))[1] == "worker_failed"
            )
            # the other session keeps working, and new sessions can be made
            assert call(api, "POST", session_path(survivor, "step"), {"actions": [1]})[0] == 200
            with session(api, small_config) as fresh:
                assert call(api, "POST", session_path(fresh, "reset"), {})[0] == 200
        assert call(api, "DELETE", session_path(doomed))[0] == 200  # a lost session can be closed
    wait_until(lambda: health()["status"] == "ok", 30, 0.05, "status ok")
    pids = {w["pid"] for w in health()["workers"]}
    assert victim["pid"] not in pids and len(pids) == 2


def test_idle_sessions_are_reaped(small_config: dict[str, Any]) -> None:
    settings = ServerSettings(workers=1, idle_timeout_s=0.3)
    with TestClient(create_app(settings), raise_server_exceptions=False) as api:
        with session(api, small_config) as sid:
            call(api, "POST", session_path(sid, "reset"), {})
            wait_until(lambda: call(api, "GET", "/v1/health")[1]["sessions_reaped"] == 1, 10, 0.05,
                       "the reaper")  # fmt: skip
            status, code, _ = error_of(
                call(api, "POST", session_path(sid, "step"), {"actions": [1]})
            )
            assert (status, code) == (404, "session_not_found")
            health = call(api, "GET", "/v1/health")[1]
            assert health["sessions"] == 0 and health["workers"][0]["envs"] == 0


def test_a_silent_worker_is_killed_and_replaced(small_config: dict[str, Any]) -> None:
    """A worker that stops answering (here: SIGSTOP) fails the request in worker_timeout_s."""
    settings = ServerSettings(workers=1, worker_timeout_s=3.0)
    with TestClient(create_app(settings), raise_server_exceptions=False) as api:
        with session(api, small_config) as sid:
            assert call(api, "POST", session_path(sid, "reset"), {})[0] == 200
            os.kill(call(api, "GET", "/v1/health")[1]["workers"][0]["pid"], signal.SIGSTOP)
            started = time.monotonic()
            status, code, message = error_of(
                call(api, "POST", session_path(sid, "step"), {"actions": [1]})
            )
            assert (status, code) == (503, "worker_failed") and "did not answer" in message
            assert 2.5 < time.monotonic() - started < 10
        wait_until(
            lambda: call(api, "GET", "/v1/health")[1]["status"] == "ok", 30, 0.05, "status ok"
        )
        assert call(api, "GET", "/v1/health")[1]["workers_replaced"] == 1
        with session(api, small_config) as sid:
            assert call(api, "POST", session_path(sid, "reset"), {})[0] == 200


def test_settings_read_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MULTION_WORKERS", "3")
    monkeypatch.setenv("MULTION_IDLE_TIMEOUT_S", "12.5")
    settings = ServerSettings()
    assert settings.workers == 3 and settings.idle_timeout_s == 12.5


def test_config_dicts_round_trip() -> None:
    config = EnvConfig(camera=CameraConfig(width=64, height=48), sensors=("rgb", "gps"))
    assert env_config_from_dict(env_config_to_dict(config)) == config
    assert env_config_from_dict({}) == EnvConfig()
    with pytest.raises(ConfigError, match=r"unknown field 'maps\.egosize'"):
        env_config_from_dict({"maps": {"egosize": 3}})
    with pytest.raises(ConfigError, match="'navgrid.floor_z' must be a number or null"):
        env_config_from_dict({"navgrid": {"floor_z": "low"}})
