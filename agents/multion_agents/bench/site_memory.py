"""``multion bench --only site-memory``: what ``n`` train envs in one process hold once every
goal site of every train house is cached (issue 44).

A child process (its own RSS, under an address-space limit) opens ``n`` envs of the reset
bench's config, resets each, then through each env's own view of the site cache marches (or
reads) every site field of the 61 train houses, as a long training run's envs end up doing,
and resets each env five more times. Its resident set is printed after the imports, with the
envs open, and with every site cached, with the fields marched in all: one process-wide cache
marches each field once and holds it once, whatever ``n``; per-env caches (before the
follow-up to issue 44) marched and held them ``n`` times. The probe uses only the env API, so
the same command on an older commit measures that commit.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

from multion.config.codec import env_config_to_dict
from multion_agents.bench.reset import bench_config

PROBE = """
import json, resource, sys, time
limit = int(sys.argv[3])
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
from multion.config.codec import env_config_from_dict
from multion.scenes.registry import scene_ids
from multion.task.env import MultiONEnv

def mib(key):
    with open("/proc/self/status") as status:
        return next(int(row.split()[1]) / 1024 for row in status if row.startswith(key + ":"))

config = env_config_from_dict(json.loads(sys.argv[1]))
imported = mib("VmRSS")
envs = [MultiONEnv(config) for _ in range(int(sys.argv[2]))]
for seed, env in enumerate(envs):
    env.reset(seed=seed)
opened = mib("VmRSS")
before = sum(env._goal_sites.marched for env in envs)
tick = time.perf_counter()
for env in envs:
    sites = env._goal_sites  # the env's view, made at its first reset
    for scene in scene_ids("train")[: int(sys.argv[4])]:
        house = sites.house(scene, env.sim.load_scene(scene))
        for site in range(len(house.sites)):
            sites.values(house, site)
warm_s = time.perf_counter() - tick
warm_marched = sum(env._goal_sites.marched for env in envs) - before
for env in envs:
    for _ in range(5):
        env.reset()
print(json.dumps({
    "imported_mib": imported, "open_mib": opened, "warm_mib": mib("VmRSS"),
    "peak_mib": mib("VmHWM"), "warm_s": warm_s, "warm_marched": warm_marched,
    "marched": sum(env._goal_sites.marched for env in envs),
}))
"""


def run_site_memory_bench(
    envs: int = 8, num_goals: int = 3, limit_gib: int = 12, houses: int = 61
) -> dict[str, float]:
    """Print and return the probe's figures for ``envs`` envs in one process, every site of
    the first ``houses`` train houses cached (61: all)."""
    config = json.dumps(env_config_to_dict(bench_config(num_goals, "sites")))
    print(
        f"site cache memory: {envs} train envs ({num_goals}-ON, the reset bench's config) in one "
        f"process under a {limit_gib} GiB address-space limit, every site of {houses} train "
        "houses cached through each env"
    )
    tick = time.monotonic()
    output = subprocess.run(
        [sys.executable, "-c", PROBE, config, str(envs), str(limit_gib * 2**30), str(houses)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    figures: dict[str, float] = json.loads(output.splitlines()[-1])
    print(
        f"  RSS: imports {figures['imported_mib']:.0f} MiB, {envs} envs open "
        f"{figures['open_mib']:.0f} MiB, every site cached {figures['warm_mib']:.0f} MiB "
        f"(peak {figures['peak_mib']:.0f} MiB); caching them marched "
        f"{figures['warm_marched']:.0f} fields in {figures['warm_s']:.0f} s, "
        f"{figures['marched']:.0f} in all [{time.monotonic() - tick:.0f} s]"
    )
    return figures
