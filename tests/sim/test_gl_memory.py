"""What a ``gl`` world costs (issue 43): the memory estimate charges the project's OpenGL
renderer what it holds, measured here: its context once per process and a little per env, not
the EGL plugin's 768 MiB per env."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig
from multion.task.memory import (
    EGL_WORLD_BYTES,
    GL_CONTEXT_BYTES,
    GL_ENV_BYTES,
    GL_THREAD_BYTES,
    estimate_env_bytes,
    estimate_process_bytes,
    process_share,
)

MiB = 2**20
NUM_ENVS = 3
PROBE = """
import json, sys
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig
from multion.task.env import MultiONEnv

def status(key):
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) * 1024 for l in f if l.startswith(key + ":"))

renderer, size, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
camera = CameraConfig(width=size, height=size, renderer=renderer)
config = EnvConfig(camera=camera, sensors=("rgb", "depth", "goal"))
rss, space, envs = status("VmRSS"), status("VmSize"), []
for seed in range(count):  # from a process with no env (and no GL context) yet
    env = MultiONEnv(config); env.reset(seed=seed); env.step(1); env.step(2); envs.append(env)
print(json.dumps({"rss": status("VmRSS") - rss, "address_space": status("VmSize") - space}))
"""


def grown(renderer: str, size: int, threads: str) -> dict[str, int]:
    """Resident and address-space growth of a fresh process opening NUM_ENVS envs, Mesa
    drawing with ``threads`` rendering threads."""
    output = subprocess.run(
        ["prlimit", f"--as={4 * 2**30}", sys.executable, "-c", PROBE, renderer, str(size),
         str(NUM_ENVS)],
        capture_output=True, text=True, timeout=300, check=True,
        env={**os.environ, "LP_NUM_THREADS": threads},
    ).stdout  # fmt: skip
    result: dict[str, int] = json.loads(output.splitlines()[-1])
    return result


@pytest.mark.parametrize(("size", "threads"), [(36, "0"), (128, "0"), (36, "1"), (36, "2")])
def test_the_gl_charge_bounds_and_fits_what_gl_worlds_hold(
    gl: None, size: int, threads: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each rendering thread adds ~144 MiB of address space to a context: the full suite ran
    this probe with LP_NUM_THREADS=1 (set by an earlier EGL test) and the old charge, made for
    0 threads, no longer bounded it."""
    monkeypatch.setenv("LP_NUM_THREADS", threads)
    camera = CameraConfig(width=size, height=size, renderer="gl")
    config = EnvConfig(camera=camera, sensors=("rgb", "depth", "goal"))
    gl_grown, tiny_grown = grown("gl", size, threads), grown("tiny", size, threads)
    print(f"{size}², {threads} threads: gl {gl_grown}, tiny {tiny_grown} ({NUM_ENVS} envs)")
    # the whole estimate bounds the process's growth, in address space too (workers' limit)
    assert gl_grown["address_space"] <= estimate_process_bytes(config, NUM_ENVS)
    # the renderer's charge (one context, then each env's part) bounds what gl adds over tiny,
    # and is within 1.5 times it
    gl_extra = max(gl_grown[k] - tiny_grown[k] for k in ("rss", "address_space"))
    charge = process_share(config).gl_context + NUM_ENVS * GL_ENV_BYTES
    assert gl_extra <= charge <= 1.5 * gl_extra
    assert process_share(config).gl_context == GL_CONTEXT_BYTES + int(threads) * GL_THREAD_BYTES
    tiny_config = EnvConfig(camera=CameraConfig(width=size, height=size), sensors=config.sensors)
    assert estimate_env_bytes(config) - estimate_env_bytes(tiny_config) == GL_ENV_BYTES
    assert process_share(tiny_config).gl_context == 0


def test_without_lp_num_threads_a_context_is_charged_one_thread(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The gl renderer sets 0 threads, PyBullet's EGL plugin 1, whichever a worker opens
    first: unset, the charge takes the larger."""
    gl_config = EnvConfig(camera=CameraConfig(renderer="gl"))
    monkeypatch.delenv("LP_NUM_THREADS", raising=False)
    assert process_share(gl_config).gl_context == GL_CONTEXT_BYTES + GL_THREAD_BYTES
    monkeypatch.setenv("LP_NUM_THREADS", "nonsense")
    assert process_share(gl_config).gl_context == GL_CONTEXT_BYTES + GL_THREAD_BYTES


def test_auto_is_charged_as_gl_and_egl_as_the_plugin() -> None:
    def charge(renderer: str) -> int:
        camera = CameraConfig(renderer=renderer)
        return estimate_env_bytes(EnvConfig(camera=camera)) - estimate_env_bytes(EnvConfig())

    assert charge("auto") == charge("gl") == GL_ENV_BYTES < EGL_WORLD_BYTES == charge("egl")
    contexts = {r: process_share(EnvConfig(camera=CameraConfig(renderer=r))).gl_context
                for r in ("tiny", "gl", "auto", "egl")}  # fmt: skip
    gl_context = contexts["gl"]
    assert contexts == {"tiny": 0, "gl": gl_context, "auto": gl_context, "egl": 0}


READY = """
import json
from multion.api import worker_process
from multion.sim.gl import context
message = worker_process.ready_message()
print(json.dumps({"renderer": message["renderer"], "context_open": context._context is not None}))
"""


def test_a_worker_reports_auto_without_holding_a_context(gl: None) -> None:
    """The ready message's GL probe runs in a child process: a worker holds a context (~60 MiB
    resident, ~280 MiB of address space) only once an env of its own renders with gl."""
    output = subprocess.run(
        [sys.executable, "-c", READY], capture_output=True, text=True, timeout=120, check=True
    ).stdout
    answer = json.loads(output.splitlines()[-1])
    assert answer == {"renderer": {"auto": "gl", "gl_unavailable": None}, "context_open": False}
