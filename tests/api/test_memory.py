"""Memory is bounded: estimates checked before workers allocate, workers under RLIMIT_AS, memory
given back when sessions close."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion.api.workers import WORKER_RESERVED_BYTES
from multion.config.codec import session_config_from_dict
from multion.task.memory import estimate_env_bytes, mib
from multion_client.protocol import CONTENT_TYPE, decode, encode, session_path

WORKER_MB = 1500  # room for a few small environments per worker


@pytest.fixture(scope="module")
def api() -> Iterator[TestClient]:
    settings = ServerSettings(workers=2, worker_memory_mb=WORKER_MB, max_envs_per_session=64)
    with TestClient(create_app(settings), raise_server_exceptions=False) as client:
        yield client


def call(api: TestClient, method: str, path: str, body: Any = None) -> tuple[int, Any]:
    content = None if body is None else encode(body)
    response = api.request(method, path, content=content, headers={"content-type": CONTENT_TYPE})
    assert response.status_code < 500, response.content
    return response.status_code, decode(response.content)


def rss_mib(pid: int) -> float:
    with open(f"/proc/{pid}/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


def worker_pids(api: TestClient) -> list[int]:
    return [w["pid"] for w in call(api, "GET", "/v1/health")[1]["workers"]]


def test_workers_run_under_the_address_space_limit(api: TestClient) -> None:
    for pid in worker_pids(api):
        with open(f"/proc/{pid}/limits") as limits:
            line = next(row for row in limits if row.startswith("Max address space"))
        assert line.split()[3:5] == [str(WORKER_MB * 2**20)] * 2


def test_a_config_that_can_never_fit_is_refused_with_its_estimate(
    api: TestClient, small_config: dict[str, Any]
) -> None:
    config = {
        **small_config,
        "camera": {"width": 1024, "height": 1024},
        "navgrid": {"cell_size": 0.02},
        "maps": {"ego_size": 1001},
        "sensors": ["rgb", "depth", "oracle_map"],
    }
    assert (
        estimate_env_bytes(session_config_from_dict(config)[0])
        > WORKER_MB * 2**20 - WORKER_RESERVED_BYTES
    )
    status, body = call(api, "POST", "/v1/sessions", {"config": config})
    assert status == 422 and body["error"]["code"] == "invalid_config"
    assert "MiB, more than a simulator worker of this server may hold" in body["error"]["message"]
    assert call(api, "GET", "/v1/health")[1]["sessions"] == 0


def test_sessions_beyond_the_workers_room_get_429_until_others_close(
    api: TestClient, small_config: dict[str, Any]
) -> None:
    per_env = estimate_env_bytes(session_config_from_dict(small_config)[0])
    room = 2 * ((WORKER_MB * 2**20 - WORKER_RESERVED_BYTES) // per_env)
    status, body = call(api, "POST", "/v1/sessions", {"config": small_config, "num_envs": room})
    assert status == 201, body
    first = body["session_id"]
    status, body = call(api, "POST", "/v1/sessions", {"config": small_config})
    assert status == 429 and body["error"]["code"] == "memory_budget_exceeded"
    assert f"need up to {mib(per_env)} MiB each" in body["error"]["message"]
    call(api, "DELETE", session_path(first))
    status, body = call(api, "POST", "/v1/sessions", {"config": small_config})
    assert status == 201
    call(api, "DELETE", session_path(body["session_id"]))


def test_closing_sessions_gives_memory_back() -> None:
    # houses build many small objects, the kind glibc keeps after they are freed
    config = {"split": "val", "sensors": ["rgb", "depth", "goal", "oracle_map"]}
    with TestClient(create_app(ServerSettings(workers=1)), raise_server_exceptions=False) as api:
        check_memory_comes_back(api, config)


def check_memory_comes_back(api: TestClient, config: dict[str, Any]) -> None:
    pid = worker_pids(api)[0]
    before = rss_mib(pid)
    sessions = []
    for seed in range(8):
        status, body = call(api, "POST", "/v1/sessions", {"config": config, "num_envs": 2})
        assert status == 201
        sessions.append(body["session_id"])
        assert (
            call(
                api, "POST", session_path(body["session_id"], "reset"), {"seeds": [seed, seed + 1]}
            )[0]
            == 200
        )
    peak = rss_mib(pid)
    for session_id in sessions:
        call(api, "DELETE", session_path(session_id))
    after = rss_mib(pid)
    print(f"worker RSS: fresh {before:.0f}, 16 envs {peak:.0f}, closed {after:.0f} MiB")
    assert peak - before > 150  # the sessions really held memory
    assert after - before < 0.15 * (peak - before), (before, peak, after)  # 0.29 without trim


PROBE = """
import gc, json, sys
from multion.config.codec import session_config_from_dict
from multion.task.env import MultiONEnv
from multion.task.memory import estimate_process_bytes

def rss():
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) * 1024 for l in f if l.startswith("VmRSS:"))

config, episodes = session_config_from_dict(json.loads(sys.argv[1]))
warm = MultiONEnv(config, episodes); warm.reset(seed=0); warm.step(1); warm.close(); del warm
gc.collect()
before, envs = rss(), []
for seed in range(3):
    env = MultiONEnv(config, episodes); env.reset(seed=seed); env.step(1); envs.append(env)
# the envs' own memory, and their process's goal-site cache once (train)
print(json.dumps({"per_env": (rss() - before) / 3, "estimate": estimate_process_bytes(config, 3) / 3}))
"""


@pytest.mark.parametrize(
    "change",
    [
        {"camera": {"width": 512, "height": 512}, "sensors": ["rgb", "depth", "goal_mask"]},
        # the packaged episodes are checked on the default grid: sample train episodes instead
        {"split": "train", "camera": {"width": 64, "height": 64}, "navgrid": {"cell_size": 0.02}},
    ],
)
def test_the_estimate_bounds_what_an_environment_holds(change: dict[str, Any]) -> None:
    config = {"split": "val", **change}
    output = subprocess.run(
        ["prlimit", f"--as={6 * 2**30}", sys.executable, "-c", PROBE, json.dumps(config)],
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    ).stdout
    measured = json.loads(output.splitlines()[-1])
    assert 0 < measured["per_env"] <= measured["estimate"]
