"""Errors by type (issue 45 item 2): the task's and the configs' errors are the client's wire
errors, which the worker answers with their own code and status; a builtin raised in the env is
a bug, a logged 500, and the worker goes on serving."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from msgpack_calls import post

from multion.api import worker_process
from multion.api.app import create_app
from multion.api.local_server import LocalServerError
from multion.api.settings import ServerSettings
from multion.api.workers import Worker
from multion.config.datasets import DatasetError
from multion.config.errors import UsageError
from multion.config.ranges import ConfigError
from multion.leaderboard.challenge import ChallengeError
from multion.leaderboard.storage import StorageError
from multion.scenes.registry import SceneIdError
from multion.sim.camera import RendererUnavailableError
from multion.sim.world import MeshSceneError
from multion.task.env import MultiONEnv
from multion.task.errors import (
    BadEpisodeError,
    BadResetOptionError,
    EpisodeNotFoundError,
    EpisodeOverError,
    IllegalActionError,
    TaskError,
)
from multion.video.encoder import EncoderUnavailable
from multion.video.stored import VideoError
from multion_agents.agent import AgentError
from multion_agents.evaluate import EpisodeMismatchError
from multion_agents.report.document import DocumentError
from multion_agents.report.runs import RunError
from multion_client import errors
from multion_client.protocol import session_path

SETTINGS = ServerSettings(workers=1, max_sessions=2, max_envs_per_session=2, idle_timeout_s=600)
SECRET = "operands could not be broadcast together (a stand-in numpy bug)"


@pytest.mark.parametrize(
    ("error_class", "wire_class", "builtin"),
    [
        (IllegalActionError, errors.InvalidAction, ValueError),
        (EpisodeOverError, errors.EpisodeOver, RuntimeError),
        (BadEpisodeError, errors.InvalidEpisode, ValueError),
        (EpisodeNotFoundError, errors.InvalidEpisode, ValueError),
        (BadResetOptionError, errors.BadRequest, ValueError),
        (ConfigError, errors.InvalidConfig, ValueError),
        (DatasetError, errors.InvalidConfig, ValueError),
        (SceneIdError, errors.InvalidConfig, ValueError),
        (MeshSceneError, errors.InvalidConfig, ValueError),
        (RendererUnavailableError, errors.InvalidConfig, ValueError),
    ],
)
def test_caller_errors_are_wire_errors_with_a_bare_message(
    error_class: type[Exception], wire_class: type[errors.MultiONError], builtin: type[Exception]
) -> None:
    error = error_class("scene_id: no such scene 'castle-1'")
    assert isinstance(error, wire_class) and isinstance(error, UsageError)
    assert isinstance(error, builtin)  # code catching the old builtin keeps working
    assert isinstance(error, errors.MultiONError)
    assert (error.code, error.status) == (wire_class.code, wire_class.status)
    assert str(error) == error.message == "scene_id: no such scene 'castle-1'"
    assert error.to_wire() == {"error": {"code": wire_class.code, "message": error.message}}


def test_every_package_roots_its_errors_in_usage_error() -> None:
    checkpoint = pytest.importorskip("multion_agents.learned.checkpoint")
    roots = [
        (ConfigError, ValueError),
        (DatasetError, ValueError),
        (SceneIdError, ValueError),
        (MeshSceneError, ValueError),
        (RendererUnavailableError, ValueError),
        (TaskError, UsageError),
        (VideoError, ValueError),
        (EncoderUnavailable, RuntimeError),
        (StorageError, ValueError),
        (ChallengeError, ValueError),
        (LocalServerError, RuntimeError),
        (DocumentError, ValueError),
        (RunError, ValueError),
        (AgentError, ValueError),
        (checkpoint.CheckpointError, ValueError),
        (EpisodeMismatchError, RuntimeError),
    ]
    for error_class, builtin in roots:
        assert issubclass(error_class, UsageError), error_class
        assert issubclass(error_class, builtin), error_class
    assert not issubclass(UsageError, ValueError)  # a builtin ValueError is never a UsageError


def _create(shards: dict[str, worker_process.Shard], config: dict[str, Any]) -> dict[str, Any]:
    payload = {"config": config, "num_envs": 1, "auto_reset": False}
    return worker_process.handle(shards, "create", "s", payload)[0]


def test_worker_answers_a_wire_error_with_its_own_code_and_status(
    small_config: dict[str, Any],
) -> None:
    shards: dict[str, worker_process.Shard] = {}
    assert _create(shards, small_config)["ok"]
    episode = dict(small_config["episodes"][0], scene_id="castle-1")
    cases = [
        ({"episode": episode}, 422, "invalid_episode", "reset of environment 0 failed: "),
        ({"episode_index": 10**6}, 422, "invalid_episode", "reset of environment 0 failed: "),
        ({"episode_idx": 0}, 400, "bad_request", "reset of environment 0 failed: "),
    ]
    for options, status, code, prefix in cases:
        header, parts = worker_process.handle(
            shards, "reset", "s", {"seeds": [None], "options": [options]}
        )
        assert (header["ok"], header["status"], header["code"], parts) == (False, status, code, [])
        assert header["message"].startswith(prefix) and "traceback" not in header
    assert (
        "castle-1"
        in worker_process.handle(
            shards, "reset", "s", {"seeds": [None], "options": [{"episode": episode}]}
        )[0]["message"]
    )
    # the env decides that its episode is over; the worker asks it before stepping any env
    header, _ = worker_process.handle(shards, "step", "s", {"actions": [1]})
    assert (header["status"], header["code"]) == (409, "episode_over")
    assert header["message"] == "environment 0: the episode is over; call reset() before step()"
    worker_process.handle(shards, "close", "s", None)


def test_a_builtin_error_in_the_env_is_a_bug_and_the_worker_goes_on(
    small_config: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    def buggy_init(self: MultiONEnv, *args: object, **kwargs: object) -> None:
        raise ValueError(SECRET)  # not the caller's mistake: no 4xx

    shards: dict[str, worker_process.Shard] = {}
    monkeypatch.setattr(MultiONEnv, "__init__", buggy_init)
    header = _create(shards, small_config)
    assert (header["code"], header["message"]) == (
        "internal_error",
        worker_process.INTERNAL_FAILURE,
    )
    assert "ValueError" in header["traceback"] and SECRET in header["traceback"]
    assert "buggy_init" in header["traceback"] and shards == {}
    monkeypatch.undo()
    assert _create(shards, small_config)["ok"]
    assert worker_process.handle(shards, "reset", "s", {"seeds": [0], "options": [None]})[0]["ok"]
    assert worker_process.handle(shards, "step", "s", {"actions": [1]})[0]["ok"]
    worker_process.handle(shards, "close", "s", None)


@pytest.fixture(scope="module")
def api() -> Iterator[TestClient]:
    with TestClient(create_app(SETTINGS), raise_server_exceptions=False) as client:
        yield client


def test_server_answers_4xx_for_bad_input_and_a_logged_500_for_a_builtin(
    api: TestClient,
    small_config: dict[str, Any],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    # the worker's commands run here, in this process, so that a bug can be put into the env
    local_shards: dict[str, worker_process.Shard] = {}

    async def in_process_request(
        self: Worker, command: str, shard_id: str, payload: Any, timeout_s: float
    ) -> worker_process.Reply:
        header, parts = worker_process.handle(local_shards, command, shard_id, payload)
        return {**header, "parts": len(parts)}, parts

    monkeypatch.setattr(Worker, "request", in_process_request)
    episode = dict(small_config["episodes"][0], scene_id="castle-1")
    status, body = post(api, "/v1/sessions", {"config": {**small_config, "episodes": [episode]}})
    assert (status, body["error"]["code"]) == (422, "invalid_episode") and "castle-1" in str(body)

    def buggy_init(self: MultiONEnv, *args: object, **kwargs: object) -> None:
        raise ValueError(SECRET)

    with monkeypatch.context() as bug:
        bug.setattr(MultiONEnv, "__init__", buggy_init)
        with caplog.at_level("ERROR", logger="multion.api"):
            status, body = post(api, "/v1/sessions", {"config": small_config, "num_envs": 1})
    assert (status, body["error"]["code"]) == (500, "internal_error")
    assert SECRET not in body["error"]["message"]
    incident = body["error"]["message"].split("incident ")[1].split(")")[0]
    assert f"incident {incident}" in caplog.text
    assert "Traceback" in caplog.text and f"ValueError: {SECRET}" in caplog.text

    # the same worker goes on: a session is created, reset, refused a bad option and stepped
    status, body = post(api, "/v1/sessions", {"config": small_config, "num_envs": 1})
    assert status == 201, body
    sid = body["session_id"]
    assert post(api, session_path(sid, "reset"), {"seeds": [0]})[0] == 200
    status, body = post(api, session_path(sid, "reset"), {"options": [{"episode_index": 10**6}]})
    assert (status, body["error"]["code"]) == (422, "invalid_episode")
    assert post(api, session_path(sid, "reset"), {"seeds": [0]})[0] == 200
    assert post(api, session_path(sid, "step"), {"actions": [1]})[0] == 200
    assert api.delete(session_path(sid)).status_code == 200


def test_a_mesh_scene_without_a_floor_is_the_callers_mistake(tmp_path: Path) -> None:
    from multion.config.sim import NavGridConfig
    from multion.sim.navgrid import build_navgrid
    from multion.sim.world import PyBulletWorld

    wall = tmp_path / "wall.obj"  # one upright 4 m x 2.5 m quad: nothing to stand on
    wall.write_text("v 0 0 0\nv 4 0 0\nv 4 0 2.5\nv 0 0 2.5\nf 1 2 3\nf 1 3 4\n")
    with pytest.raises(MeshSceneError, match="no floor found|no navigable floor") as raised:
        build_navgrid(PyBulletWorld.from_mesh(wall), NavGridConfig())
    assert (raised.value.code, raised.value.status) == ("invalid_config", 422)
