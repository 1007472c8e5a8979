"""``multion bench --only memory``: what workers hold, measured against the server's estimates.

1. The largest config the ranges allow (1024² images of every kind, a 0.02 m grid, a 1001-cell
   map crop, 8 goals) in a house: one environment's peak memory in a process of its own,
   against :func:`~multion.task.memory.estimate_env_bytes` (the estimate must bound it).
2. A server worker that opens ``sessions`` sessions of the default config one after another,
   resets each, then closes them all: its memory fresh, with all open, and after, against a
   fresh worker (closing must give the memory back).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

from multion.api.local_server import LocalServer
from multion.config.codec import env_config_from_dict
from multion.task.memory import estimate_env_bytes, mib
from multion_client import Client

LARGEST: dict = {
    "camera": {"width": 1024, "height": 1024},
    "navgrid": {"cell_size": 0.02},
    "maps": {"ego_size": 1001},
    "task": {"num_goals": 8},
    "split": "train",  # sampled online: no packaged 8-goal episodes
    "sensors": ["rgb", "depth", "goal", "goal_mask", "oracle_map", "oracle_ego_map", "gps"],
}

_PEAK_PROBE = """
import json, sys
from multion.config.codec import env_config_from_dict
from multion.task.env import MultiONEnv

def status(key):
    with open("/proc/self/status") as f:
        return next(int(r.split()[1]) * 1024 for r in f if r.startswith(key + ":"))

before = status("VmRSS")
env = MultiONEnv(env_config_from_dict(json.loads(sys.argv[1])))
env.reset(seed=0)
for step in range(20):
    env.step(1 + step % 3)
print(json.dumps({"before": before, "peak": status("VmHWM")}))
"""


def bench_memory(sessions: int = 64) -> dict[str, float]:
    print("memory: one environment of the largest allowed config (peak, in its own process)")
    estimate = estimate_env_bytes(env_config_from_dict(LARGEST))
    started = time.monotonic()
    output = subprocess.run(
        [sys.executable, "-c", _PEAK_PROBE, json.dumps(LARGEST)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    probe = json.loads(output.splitlines()[-1])
    held = probe["peak"] - probe["before"]
    print(
        f"  peak {mib(probe['peak'])} MiB ({mib(held)} MiB above the imports) vs estimate "
        f"{mib(estimate)} MiB: ratio {held / estimate:.2f} (must be ≤ 1) "
        f"[{time.monotonic() - started:.0f} s]"
    )
    figures = {"largest_peak_mib": probe["peak"] / 2**20, "largest_estimate_mib": estimate / 2**20}
    figures.update(_sessions_open_and_closed(sessions))
    return figures


def _sessions_open_and_closed(count: int) -> dict[str, float]:
    config = {"split": "val", "sensors": ["rgb", "depth", "goal", "oracle_map"]}
    per_env = estimate_env_bytes(env_config_from_dict(config))
    room_mb = mib(count * per_env) + 1024 + 512
    print(f"memory: {count} default sessions (256², oracle map) opened, reset, then closed")
    with LocalServer(workers=1, options=["--worker-memory-mb", str(room_mb)]) as server:
        with Client(server.url, timeout=600) as client:
            pid = client.health()["workers"][0]["pid"]
            fresh = _rss(pid)
            ids = []
            for index in range(count):
                info = client.create_session(config)
                client.reset(info.session_id, seeds=[index])
                ids.append(info.session_id)
            open_ = _rss(pid)
            for session_id in ids:
                client.close_session(session_id)
            closed = _rss(pid)
    print(
        f"  worker RSS: fresh {fresh:.0f} MiB, {count} open {open_:.0f} MiB, all closed "
        f"{closed:.0f} MiB: {closed / fresh:.2f}× a fresh worker "
        f"(kept {closed - fresh:.0f} of the {open_ - fresh:.0f} MiB the sessions took)"
    )
    return {"fresh_mib": fresh, "open_mib": open_, "closed_mib": closed}


def _rss(pid: int) -> float:
    with open(f"/proc/{pid}/status") as status:
        return next(int(r.split()[1]) / 1024 for r in status if r.startswith("VmRSS:"))
