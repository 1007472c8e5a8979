"""``multion bench`` (HTTP part): the cost of the client-server API on this machine.

Measures, with local servers on free loopback ports (always stopped at the end):

* steps/s of one environment over HTTP (``RemoteEnv``) vs in-process (``MultiONEnv``) at each
  resolution and with each renderer asked for (3-ON, RGB-D + goal, the first episode of the
  packaged val set), and the CPU each remote step costs the client, the HTTP process and the
  simulator worker (read from ``/proc``: they run one after another for each request);
* aggregate steps/s of a 4-env ``RemoteVectorEnv`` against ``--workers 2`` vs ``--workers 1``;
* the server's resident memory (HTTP process + workers) after 50 and after N short episodes.

Timings alternate between the contenders in short blocks, so that background load on the
machine hits both alike; only ``step`` calls are timed.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from multion.api.local_server import LocalServer
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig
from multion.sim.camera import egl_plugin_loads, why_not_gl
from multion.sim.simulator import Simulator
from multion.task.env import MultiONEnv
from multion.task.sampling import sample_episode
from multion_client import RemoteEnv, RemoteVectorEnv

BLOCK_STEPS = 20
MEMORY_SCENE = "room-6x4"


def run_http_bench(
    resolutions: tuple[int, ...] = (256, 128),
    steps: int = 200,
    episodes_for_memory: int = 1000,
    vector_steps: int = 60,
    vector_resolution: int = 256,
    verbose: bool = True,
    server_options: list[str] | None = None,
    renderers: tuple[str, ...] = ("tiny",),
) -> dict[str, Any]:
    """Run every measurement, print a small table (``verbose``) and return the numbers.

    ``server_options`` are extra ``multion serve`` arguments, e.g. ``["--http", "h11"]``.
    ``renderers``: the single-env rows are measured with each; the vector env renders with
    the last one.
    """
    say = print if verbose else _quiet
    result: dict[str, Any] = {"cpu_count": os.cpu_count(), "load_average": os.getloadavg()}
    result["server_options"] = options = list(server_options or [])
    with contextlib.ExitStack() as stack:
        one = LocalServer(workers=1, options=options)
        two = LocalServer(workers=2, options=options)
        for server in (one, two):
            stack.callback(server.stop)
            server.launch()
        for server in (one, two):
            server.wait_ready()
        say(f"servers up: {one.url} (1 worker), {two.url} (2 workers)")
        result["single"] = {
            f"{renderer} {res}": _single_env(one, res, renderer, steps, say)
            for renderer in renderers
            for res in resolutions
        }
        result["vector"] = _vector(
            one.url, two.url, vector_resolution, renderers[-1], vector_steps, say
        )
    result["vector"]["machine_headroom"] = _parallel_headroom(
        vector_resolution, renderers[-1], vector_steps
    )
    result["memory"] = _memory(episodes_for_memory, say, options)
    if verbose:
        print_table(result)
    return result


def http_renderers(requested: str) -> tuple[tuple[str, ...], str | None]:
    """What ``bench --renderer REQUESTED`` measures over HTTP, or why it cannot: "all" is tiny,
    and gl beside it where an OpenGL context opens."""
    gl_missing = why_not_gl()
    if requested == "all":
        return ("tiny",) if gl_missing else ("tiny", "gl"), None
    if requested == "gl" and gl_missing:
        return (), f"gl does not open here: {gl_missing}"
    if requested == "egl" and not egl_plugin_loads():
        return (), "pybullet's eglRenderer plugin does not load here"
    return (requested,), None


def print_table(result: dict[str, Any]) -> None:
    load = ", ".join(f"{x:.2f}" for x in result["load_average"])
    print(f"\nMultiON HTTP benchmark — {result['cpu_count']} CPUs, load average {load} at start")
    print(f"server options: {' '.join(result.get('server_options') or []) or '(defaults)'}")
    print(f"{'':>38} CPU ms per step: in-process | remote: client, HTTP process, worker")
    print(f"{'renderer RGB-D':>15} {'in-process':>11} {'HTTP':>6} {'ratio':>6} {'':>23} ")
    for key, row in result["single"].items():
        renderer, res = key.split()
        print(
            f"{renderer:>6} {res:>4}x{res:<4} {row['in_process_sps']:>11.1f} {row['http_sps']:>6.1f}"
            f" {row['ratio']:>6.2f} {row['in_process_cpu_ms']:>32.2f} |"
            f" {row['client_cpu_ms']:>6.2f} {row['http_cpu_ms']:>6.2f} {row['worker_cpu_ms']:>6.2f}"
        )
    print(
        "  targets with gl (issue 54): HTTP/in-process ≥ 0.7 at 256², ≥ 0.6 at 128²; client and "
        "HTTP CPU ≤ 0.8 ms per step at 256²"
    )
    vec = result["vector"]
    print(
        f"RemoteVectorEnv, {vec['num_envs']} envs at {vec['resolution']}² ({vec['renderer']}): "
        f"{vec['workers_1_sps']:.1f} steps/s with 1 worker, {vec['workers_2_sps']:.1f} with 2 "
        f"→ ×{vec['ratio']:.2f} (target ≥ 1.6)"
    )
    print(
        f"  (for reference: 2 in-process envs in 2 processes run ×{vec['machine_headroom']:.2f} "
        "as fast as 1 on this machine now: the most a second worker can add)"
    )
    mem = result["memory"]
    print(
        f"server RSS (HTTP process + workers): {mem['rss_mb_early']:.1f} MB after "
        f"{mem['episodes_early']} episodes, {mem['rss_mb_late']:.1f} MB after "
        f"{mem['episodes_late']} (growth {mem['growth_mb']:+.1f} MB)"
    )


# ---------------------------------------------------------------------- measurements
def _single_env(
    server: LocalServer, res: int, renderer: str, steps: int, say: Callable[[str], None]
) -> dict[str, float]:
    """``server`` has one worker, so the CPU of its children is that worker's."""
    local = MultiONEnv(EnvConfig(camera=CameraConfig(width=res, height=res, renderer=renderer)))
    remote = RemoteEnv(server.url, {"camera": {"width": res, "height": res, "renderer": renderer}})
    try:
        envs: dict[str, Any] = {"in_process": local, "http": remote}
        for env in envs.values():
            env.reset(options={"episode_index": 0})  # one house: no scene loads while timing
        rng = np.random.default_rng(res)
        totals = {name: [0, 0.0] for name in envs}
        processes = [server.pid, *_children(server.pid)]  # the HTTP process, then its worker
        cpu = np.zeros(3)  # seconds of the client, the HTTP process and its worker
        in_process_cpu = 0.0
        while totals["http"][0] < steps:
            actions = rng.integers(1, 4, BLOCK_STEPS).tolist()  # moves and turns, no FOUND
            for name, env in envs.items():
                if name == "http":
                    cpu -= _cpu_seconds(processes, client_last=True)
                started = time.process_time()
                count, seconds = _run_block(env, actions)
                if name == "http":
                    cpu += _cpu_seconds(processes, client_last=False)
                else:
                    in_process_cpu += time.process_time() - started
                totals[name][0] += count
                totals[name][1] += seconds
    finally:
        local.close()
        remote.close()
    row = {f"{name}_sps": count / seconds for name, (count, seconds) in totals.items()}
    row["ratio"] = row["http_sps"] / row["in_process_sps"]
    per_step_ms = 1000 * cpu / totals["http"][0]
    row.update(
        zip(("client_cpu_ms", "http_cpu_ms", "worker_cpu_ms"), per_step_ms.tolist(), strict=True)
    )
    # (the renderer's threads count: llvmpipe draws on every core)
    row["in_process_cpu_ms"] = 1000 * in_process_cpu / totals["in_process"][0]
    say(
        f"{renderer} {res}²: in-process {row['in_process_sps']:.1f}, HTTP {row['http_sps']:.1f}"
        f" steps/s; CPU ms per step: in-process {row['in_process_cpu_ms']:.2f}; remote: client"
        f" {per_step_ms[0]:.2f}, HTTP {per_step_ms[1]:.2f}, worker {per_step_ms[2]:.2f}"
    )
    return row


def _run_block(env: Any, actions: list[int]) -> tuple[int, float]:
    seconds = 0.0
    for action in actions:
        start = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        seconds += time.perf_counter() - start
        if terminated or truncated:
            env.reset(options={"episode_index": 0})
    return len(actions), seconds


def _vector(
    url_1: str,
    url_2: str,
    res: int,
    renderer: str,
    steps: int,
    say: Callable[[str], None],
    num_envs: int = 4,
) -> dict[str, Any]:
    config = {"camera": {"width": res, "height": res, "renderer": renderer}}
    vecs = {"workers_1": RemoteVectorEnv([url_1], num_envs, config)}
    try:
        vecs["workers_2"] = RemoteVectorEnv([url_2], num_envs, config)
        for vec in vecs.values():
            vec.reset(options={"episode_index": 0})
        rng = np.random.default_rng(0)
        totals = {name: 0.0 for name in vecs}
        for _ in range(0, steps, BLOCK_STEPS // 2):
            block = rng.integers(1, 4, (BLOCK_STEPS // 2, num_envs))
            for name, vec in vecs.items():
                start = time.perf_counter()
                for actions in block:
                    vec.step(actions)
                totals[name] += time.perf_counter() - start
    finally:
        for vec in vecs.values():
            vec.close()
    done = len(range(0, steps, BLOCK_STEPS // 2)) * (BLOCK_STEPS // 2) * num_envs
    row: dict[str, Any] = {f"{k}_sps": done / v for k, v in totals.items()}
    row.update(
        num_envs=num_envs,
        resolution=res,
        renderer=renderer,
        ratio=row["workers_2_sps"] / row["workers_1_sps"],
    )
    say(
        f"vector: 1 worker {row['workers_1_sps']:.1f}, 2 workers {row['workers_2_sps']:.1f} steps/s"
    )
    return row


def _memory(
    episodes: int, say: Callable[[str], None], options: list[str], num_envs: int = 8
) -> dict[str, Any]:
    """Short episodes (32² camera, at most 20 steps, FOUND often) on a fresh 1-worker server."""
    grid = Simulator().load_scene(MEMORY_SCENE)
    rng = np.random.default_rng(0)
    pool = [sample_episode(grid, MEMORY_SCENE, 1, rng, f"mem-{i}") for i in range(40)]
    config = {
        "task": {"num_goals": 1, "max_steps": 20},
        "camera": {"width": 32, "height": 32},
        "episodes": [e.to_dict() for e in pool if e is not None],
    }
    early = min(50, episodes)
    with LocalServer(workers=1, options=options) as server:
        vec = RemoteVectorEnv([server.url], num_envs, config)
        try:
            vec.reset(seed=0)
            ended, rss_early = 0, None
            while ended < episodes:
                actions = rng.choice(4, size=num_envs, p=[0.3, 0.4, 0.15, 0.15])
                _, _, terminated, truncated, _ = vec.step(actions)
                ended += int(np.sum(terminated | truncated))
                if rss_early is None and ended >= early:
                    rss_early = _tree_rss_mb(server.pid)
            rss_late = _tree_rss_mb(server.pid)
        finally:
            vec.close()
    assert rss_early is not None
    say(f"memory: {rss_early:.1f} MB after {early} episodes, {rss_late:.1f} MB after {ended}")
    return {
        "episodes_early": early,
        "episodes_late": ended,
        "rss_mb_early": rss_early,
        "rss_mb_late": rss_late,
        "growth_mb": rss_late - rss_early,
    }


def _parallel_headroom(res: int, renderer: str, steps: int) -> float:
    """Throughput of in-process envs in 2 processes over 1, without any server: what the
    machine (its cores, and whatever else runs on it) allows a second worker to add."""
    ctx = multiprocessing.get_context("spawn")
    rates = []
    for count in (1, 2):
        barrier, results = ctx.Barrier(count), ctx.Queue()
        procs = [
            ctx.Process(
                target=_render_steps, args=(res, renderer, steps, barrier, results), daemon=True
            )
            for _ in range(count)
        ]
        try:
            for proc in procs:
                proc.start()
            seconds = max(results.get(timeout=300) for _ in procs)
        finally:
            for proc in procs:
                proc.join(timeout=10)
                if proc.is_alive():
                    proc.kill()
        rates.append(count * steps / seconds)
    return float(rates[1] / rates[0])


def _render_steps(res: int, renderer: str, steps: int, barrier: Any, results: Any) -> None:
    env = MultiONEnv(EnvConfig(camera=CameraConfig(width=res, height=res, renderer=renderer)))
    env.reset(options={"episode_index": 0})
    barrier.wait()  # every process starts timing together
    start = time.perf_counter()
    for index in range(steps):
        env.step(2 + index % 2)
    results.put(time.perf_counter() - start)
    env.close()


# ---------------------------------------------------------------------- helpers
def _cpu_seconds(processes: list[int], client_last: bool) -> np.ndarray:
    """CPU seconds used so far by this process (the client), the server's HTTP process
    (``processes[0]``) and its children (the rest). The client's own clock is read last before
    a block and first after it, so that reading ``/proc`` is not counted as the client's."""
    client = 0.0 if client_last else time.process_time()
    server = _process_cpu_seconds(processes[0])
    children = sum(_process_cpu_seconds(child) for child in processes[1:])
    if client_last:
        client = time.process_time()
    return np.array([client, server, children])


def _process_cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of one process (0 for one that is gone)."""
    try:
        with open(f"/proc/{pid}/stat") as handle:
            fields = handle.read().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _tree_rss_mb(pid: int) -> float:
    """Resident memory of a process and its children (the simulator workers), in MB."""
    total_kb = 0
    for member in [pid, *_children(pid)]:
        with contextlib.suppress(OSError), open(f"/proc/{member}/status") as handle:
            for line in handle:
                if line.startswith("VmRSS:"):
                    total_kb += int(line.split()[1])
    return total_kb / 1024


def _children(pid: int) -> list[int]:
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        with contextlib.suppress(OSError), open(f"/proc/{entry}/stat") as handle:
            if int(handle.read().rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry))
    return found


def _quiet(text: str) -> None:
    pass


if __name__ == "__main__":
    run_http_bench()
