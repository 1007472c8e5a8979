"""Several training environments per worker process (issue 44 item 2): the same rollouts as
one environment per process, fewer processes, and a worker's error raised in the trainer."""

from __future__ import annotations

import subprocess
import sys
from collections import deque
from pathlib import Path

import pytest
import torch

from multion_agents.learned.checkpoint import build_policy
from multion_agents.learned.env_groups import EnvGroups, make_env_groups
from multion_agents.learned.env_workers import SharedProcessVectorEnv, WorkerError
from multion_agents.learned.rollout import Rollout, collect, start_episodes
from multion_agents.learned.rollout_envs import make_vector_env, training_env_config

SENSORS = ("rgb", "depth", "goal", "oracle_map")


def play(groups: EnvGroups, steps: int) -> tuple[Rollout, list[dict[str, float]]]:
    torch.manual_seed(0)
    policy = build_policy("oracle-map", training_env_config(1, SENSORS, 36, "val"))
    torch.manual_seed(7)  # the actions' stream
    finished: deque[dict[str, float]] = deque()
    try:
        live = start_episodes(groups, policy, seed=11)
        rollout, _, _ = collect(groups, policy, live, steps, finished)
    finally:
        groups.close()
    return rollout, list(finished)


def test_envs_sharing_processes_play_the_rollout_of_one_env_per_process(
    room_dataset: Path,
) -> None:
    config = training_env_config(1, SENSORS, 36, "train", None, 12, str(room_dataset))
    shared = make_env_groups(config, 6, envs_per_process=2)
    assert all(isinstance(g, SharedProcessVectorEnv) for g in shared.groups)
    # 3 envs per group, 2 per process: processes of 2 and 1 envs
    assert [len(g.worker_pids) for g in shared.groups] == [2, 2]  # type: ignore[attr-defined]
    together, together_finished = play(shared, 30)
    alone, alone_finished = play(make_env_groups(config, 6), 30)
    assert alone.dones.sum() > 0  # episodes end inside the rollout (12-step limit)
    assert torch.equal(together.actions, alone.actions)
    for key, frames in alone.frames.items():
        assert torch.equal(together.frames[key], frames), key
    for name in ("rewards", "dones", "starts", "prev_actions"):
        assert torch.equal(getattr(together, name), getattr(alone, name)), name
    assert together_finished == alone_finished  # the finished episodes' metrics


def test_a_worker_s_error_is_raised_with_its_traceback(room_dataset: Path) -> None:
    config = training_env_config(1, SENSORS, 36, "train", None, 12, str(room_dataset))
    config["camera"]["width"] = -3  # the env's own check fails in the worker
    with pytest.raises(WorkerError, match="worker process 0") as error:
        make_vector_env(config, 2, envs_per_process=2)
    assert "width" in str(error.value)


def test_envs_per_process_below_one_is_refused() -> None:
    with pytest.raises(ValueError, match="--envs-per-process 0: at least 1"):
        make_vector_env({}, 2, envs_per_process=0)


def test_the_env_processes_bench_counts_the_simulator_processes_and_their_memory() -> None:
    from multion_agents.bench.env_processes import measure

    # Another child of the caller, as a test suite's servers are (CI counted one of them).
    bystander = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    try:
        shared, alone = measure(2, 2, steps=3), measure(2, 1, steps=3)
    finally:
        bystander.kill()
        bystander.wait()
    assert shared["processes"] == 1 and alone["processes"] == 2  # nor the resource tracker
    assert 0 < shared["pss_mib"] <= shared["rss_mib"]
    assert shared["rss_mib"] < alone["rss_mib"]  # one process's imports instead of two
    assert shared["fps"] > 0 and alone["fps"] > 0
