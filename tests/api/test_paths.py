"""A client may name only dataset files (and mesh scenes) inside the server's allowed dirs."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from multion.api.app import create_app
from multion.api.cli_serve import add_arguments, settings_from_args
from multion.api.settings import ServerSettings
from multion.config.datasets import DATA_DIR, packaged_dataset_path, save_dataset
from multion.config.episode import Episode
from multion_client import errors
from multion_client.protocol import CONTENT_TYPE, decode, encode, session_path


@pytest.fixture(scope="module")
def dirs(tmp_path_factory: pytest.TempPathFactory, room_episodes: list[Episode]) -> dict[str, Path]:
    """An allowed dir and a forbidden dir beside it, each holding the same valid dataset."""
    base = tmp_path_factory.mktemp("paths")
    found = {"allowed": base / "allowed", "outside": base / "outside"}
    for where in found.values():
        save_dataset(where / "room.json.gz", room_episodes, 2, "val")
    (found["allowed"] / "link.json.gz").symlink_to(found["outside"] / "room.json.gz")
    return found


@pytest.fixture(scope="module")
def api(dirs: dict[str, Path]) -> Iterator[TestClient]:
    settings = ServerSettings(workers=1, allowed_dataset_dirs=[dirs["allowed"]])
    with TestClient(create_app(settings), raise_server_exceptions=False) as client:
        yield client


def create(api: TestClient, config: dict[str, Any]) -> tuple[int, Any]:
    body = encode({"config": config})
    response = api.post("/v1/sessions", content=body, headers={"content-type": CONTENT_TYPE})
    answer = decode(response.content)
    if response.status_code == 201:
        api.delete(session_path(answer["session_id"]))
    return response.status_code, answer


def with_dataset(path: Path | str) -> dict[str, Any]:
    return {"task": {"num_goals": 2}, "camera": {"width": 16, "height": 16}, "dataset": str(path)}


def test_a_dataset_inside_an_allowed_dir_is_accepted(
    api: TestClient, dirs: dict[str, Path]
) -> None:
    status, answer = create(api, with_dataset(dirs["allowed"] / "room.json.gz"))
    assert status == 201, answer


def test_the_packaged_datasets_are_always_allowed(api: TestClient) -> None:
    status, answer = create(api, with_dataset(packaged_dataset_path(2, "val")))
    assert status == 201, answer


@pytest.mark.parametrize(
    "name",
    [
        "outside",  # a valid dataset, but not in an allowed dir
        "dotdot",  # allowed/../outside/room.json.gz
        "symlink",  # allowed/link.json.gz -> outside/room.json.gz
        "etc",  # any other file on the server's disk
    ],
)
def test_paths_outside_the_allowed_dirs_are_refused(
    api: TestClient, dirs: dict[str, Path], name: str
) -> None:
    path = {
        "outside": dirs["outside"] / "room.json.gz",
        "dotdot": f"{dirs['allowed']}/../outside/room.json.gz",
        "symlink": dirs["allowed"] / "link.json.gz",
        "etc": "/etc/passwd",
    }[name]
    status, answer = create(api, with_dataset(path))
    assert status == 403 and answer["error"]["code"] == "path_not_allowed"
    message = answer["error"]["message"]
    assert str(path) in message and "--dataset-dir" in message
    # the client's value, never the server's directories
    for server_dir in (dirs["allowed"], DATA_DIR.resolve()):
        assert str(server_dir) not in message.replace(str(path), "")
    assert isinstance(errors.error_from_code("path_not_allowed", message, 403), errors.BadRequest)


def test_mesh_scenes_of_inline_episodes_are_checked(
    api: TestClient, small_config: dict[str, Any], dirs: dict[str, Path]
) -> None:
    episode = {**small_config["episodes"][0], "scene_id": str(dirs["outside"] / "scan.obj")}
    status, answer = create(api, {**small_config, "episodes": [episode]})
    assert status == 403 and "mesh scene" in answer["error"]["message"]
    with_session = {"config": small_config}
    response = api.post("/v1/sessions", content=encode(with_session))
    session_id = decode(response.content)["session_id"]  # procedural scene ids are not paths
    try:
        reset = api.post(
            session_path(session_id, "reset"), content=encode({"options": [{"episode": episode}]})
        )
        assert (
            reset.status_code == 403 and "mesh scene" in decode(reset.content)["error"]["message"]
        )
    finally:
        api.delete(session_path(session_id))


def test_serve_option_dataset_dir_is_repeatable(tmp_path: Path) -> None:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--dataset-dir", str(tmp_path), "--dataset-dir", "data"])
    assert settings_from_args(args).allowed_dataset_dirs == [tmp_path, Path("data")]
    assert settings_from_args(parser.parse_args([])).allowed_dataset_dirs == []


def test_allowed_dirs_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MULTION_ALLOWED_DATASET_DIRS", '["/srv/a", "/srv/b"]')
    assert ServerSettings().allowed_dataset_dirs == [Path("/srv/a"), Path("/srv/b")]
