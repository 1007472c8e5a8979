"""``multion eval`` end to end: local vs remote server, report files, clear errors."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from multion.api.local_server import LocalServer
from multion.config.datasets import save_dataset
from multion.config.episode import Episode
from multion_agents import cli_eval

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    cli_eval.add_arguments(parser)
    return cli_eval.run(parser.parse_args(argv))


def _episodes(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]


def test_local_and_remote_server_give_the_same_metrics(
    room_dataset: tuple[Path, list[Episode]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, episodes = room_dataset
    common = ["--agent", "random-oracle-found", "--task", "1-on", "--dataset", str(path)]
    common += ["--seed", "5", "--max-steps", "60", "--quiet"]
    local_out, remote_out = tmp_path / "local", tmp_path / "remote"
    in_process_out = tmp_path / "in-process"
    assert _run([*common, "--out", str(local_out), "--pictures", "2"]) == 0
    # A remote server reads only the dataset directories its operator allows.
    with LocalServer(workers=1, options=["--dataset-dir", str(path.parent)]) as server:
        assert _run([*common, "--out", str(remote_out), "--server", server.url]) == 0
    assert _run([*common, "--out", str(in_process_out), "--in-process", "--pictures", "0"]) == 0
    table = capsys.readouterr().out
    assert "Success" in table and "95% CI" in table and "episodes" in table

    local, remote = _episodes(local_out), _episodes(remote_out)
    assert [e["episode_id"] for e in local] == [e.episode_id for e in episodes]
    assert [e["metrics"] for e in local] == [e["metrics"] for e in remote]
    assert [e["metrics"] for e in local] == [e["metrics"] for e in _episodes(in_process_out)]

    summary = json.loads((local_out / "metrics.json").read_text())
    assert summary["run"]["agent"] == "random-oracle-found"
    assert summary["run"]["seed"] == 5 and summary["run"]["episodes"] == 3
    assert summary["run"]["server"]["local"] is True
    assert summary["run"]["server"]["renderer"] == "tiny"  # the default camera.renderer
    assert "goal_distance" in summary["run"]["env_config"]["sensors"]
    for key in ("success", "progress", "spl", "ppl"):
        estimate = summary["metrics"][key]
        assert estimate["low"] <= estimate["mean"] <= estimate["high"]

    pictures = sorted(local_out.glob("episode-*.png"))
    assert len(pictures) == 2
    for picture in pictures:
        assert picture.read_bytes()[:8] == PNG_SIGNATURE
        with Image.open(picture) as image:
            image.verify()
    with Image.open(pictures[0]) as image:  # the agent path is drawn in orange
        pixels = np.asarray(image.convert("RGB")).reshape(-1, 3)
    assert (pixels == (245, 130, 20)).all(axis=1).any()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--agent", "rnadom"], "unknown agent 'rnadom'"),
        (["--agent", "random", "--task", "12-on"], "unknown task '12-on'"),
        (["--agent", "random", "--episodes", "0"], "--episodes must be positive"),
        (["--agent", "random", "--split", "nope"], "unknown split 'nope'"),
        (["--agent", "random", "--server", "http://127.0.0.1:9"], "cannot reach"),
        (["--agent", "random", "--in-process", "--server", "http://x"], "exclude each other"),
    ],
)
def test_clear_errors(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert _run([*argv, "--quiet"]) == 2
    assert message in capsys.readouterr().err


def test_metrics_json_records_the_agents_own_settings(
    room_dataset: tuple[Path, list[Episode]], tmp_path: Path
) -> None:
    from dataclasses import asdict

    from multion_agents.baselines.oracle_planner import OraclePlannerSettings

    path, _ = room_dataset
    flags = ["--agent", "oracle-planner", "--task", "1-on", "--dataset", str(path), "--in-process"]
    flags += ["--episodes", "1", "--max-steps", "5", "--pictures", "0", "--quiet"]
    assert _run([*flags, "--out", str(tmp_path / "planner")]) == 0
    run = json.loads((tmp_path / "planner" / "metrics.json").read_text())["run"]
    assert run["agent_settings"] == asdict(OraclePlannerSettings())
    assert run["agent_settings"]["stuck_visits"] == 3
    flags[1] = "random"  # an agent without tunables records none
    assert _run([*flags, "--out", str(tmp_path / "random")]) == 0
    run = json.loads((tmp_path / "random" / "metrics.json").read_text())["run"]
    assert run["agent_settings"] == {}


def test_a_dataset_file_gives_the_run_its_split(
    room_dataset: tuple[Path, list[Episode]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--dataset FILE: the run records the split FILE's header names (not the default val); a
    --split that contradicts it is refused, naming both, before anything is played or written."""
    _, episodes = room_dataset
    train = tmp_path / "train-1-on.json.gz"
    save_dataset(train, episodes, 1, "train")
    flags = ["--agent", "random", "--task", "1-on", "--dataset", str(train), "--in-process"]
    flags += ["--episodes", "1", "--max-steps", "5", "--pictures", "0", "--quiet"]
    assert _run([*flags, "--out", str(tmp_path / "played")]) == 0
    assert json.loads((tmp_path / "played" / "metrics.json").read_text())["run"]["split"] == "train"
    assert _run([*flags, "--split", "val", "--out", str(tmp_path / "refused")]) == 2
    error = capsys.readouterr().err
    assert f"--split val: {train} holds train episodes" in error and "give --split train" in error
    assert not (tmp_path / "refused").exists()
    assert _run([*flags, "--split", "train", "--out", str(tmp_path / "agreed")]) == 0
    assert json.loads((tmp_path / "agreed" / "metrics.json").read_text())["run"]["split"] == "train"
