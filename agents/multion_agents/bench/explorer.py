"""``multion bench --only explorer``: the explorer's thinking time per step, before and after
issue 23, measured in one run on the same observations.

The env plays packaged 3-ON val episodes; at every step both agents, the explorer as it is
(:class:`~multion_agents.baselines.explorer.ExplorerAgent`) and as it was
(:class:`~.explorer_reference.ReferenceExplorerAgent`), get the same observation, one
after the other (which goes first alternates, so neither always finds the caches warm). Their
actions must be equal, or the bench stops: the speed-up is worth nothing if a decision changed.
The explorer plays without its look-ahead (issue 22), which changes decisions on purpose.
Rendering is not timed; only ``act``, split as :class:`~.baselines.explorer.StepTimes` splits it.
"""

from __future__ import annotations

import os
import time

from multion.config.datasets import load_dataset, packaged_dataset_path
from multion.config.episode import Episode
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion_agents.baselines.explorer import ExplorerAgent, ExplorerSettings, StepTimes
from multion_agents.bench.explorer_reference import ReferenceExplorerAgent

TARGET = 2.0
"""The issue's target: the explorer thinks at least twice as fast per step."""

PARTS = ("mapping", "planning", "rest")


def run_explorer_bench(image: int = 256, houses: int = 3, steps: int = 500) -> dict[str, float]:
    """Print and return ms per step of each part for both agents, and the ratios: the first
    3-ON val episode of each of the first ``houses`` val houses, at most ``steps`` steps each."""
    load_before = os.getloadavg()
    first_per_house: dict[str, Episode] = {}
    for episode in load_dataset(packaged_dataset_path(3, "val"), 3):
        first_per_house.setdefault(episode.scene_id, episode)
    played = list(first_per_house.values())[:houses]
    # the look-ahead of issue 22 changes decisions on purpose where the reference turned at
    # random (squeezed, no step downhill); without it both must still act alike
    reference = ReferenceExplorerAgent(seed=0)
    fast = ExplorerAgent(seed=0, settings=ExplorerSettings(look_ahead=1))
    config = EnvConfig(
        task=TaskConfig(num_goals=3, max_steps=steps),
        camera=CameraConfig(width=image, height=image),
        sensors=tuple(dict.fromkeys([*fast.sensors, "gps"])),
    )
    env = MultiONEnv(config, episodes=played)
    started, env_seconds = time.perf_counter(), 0.0
    try:
        for index, episode in enumerate(played):
            observation, _ = env.reset(options={"episode_id": episode.episode_id})
            for agent in (reference, fast):
                agent.seed(index)
                agent.reset()
            done, step = False, 0
            while not done:
                seen = {k: v for k, v in observation.items() if k in fast.sensors}
                order = (reference, fast) if step % 2 == 0 else (fast, reference)
                first, second = (agent.act(seen) for agent in order)
                if first != second:
                    raise RuntimeError(
                        f"{episode.episode_id} step {step}: the explorer chose {first} and "
                        f"{second} on the same observation; the fast path changed a decision"
                    )
                tick = time.perf_counter()
                observation, _, terminated, truncated, _ = env.step(first)
                env_seconds += time.perf_counter() - tick
                done, step = terminated or truncated, step + 1
        renderer = env.sim.renderer
    finally:
        env.close()
    wall = time.perf_counter() - started
    scenes = ", ".join(e.scene_id for e in played)
    results = _report(reference.times, fast.times, image, scenes, wall)
    env_ms = results["env_step_ms"] = 1000.0 * env_seconds / max(1, fast.times.steps)
    print(
        f"{'env step':>12} {env_ms:>10.2f} ms ({renderer} render + task, not timed above): thinking "
        f"was {_share(results['reference_total_ms'], env_ms)} of a step, now "
        f"{_share(results['fast_total_ms'], env_ms)}"
    )
    load_after = os.getloadavg()
    print(
        f"load average (1, 5, 15 min) before {_load(load_before)}, after {_load(load_after)}, "
        f"on {os.cpu_count()} CPUs (a shared machine: other processes share them)"
    )
    return results


def _report(
    reference: StepTimes, fast: StepTimes, image: int, scenes: str, wall: float
) -> dict[str, float]:
    steps = fast.steps
    print(
        f"explorer at {image}², {steps} steps of 3-ON val episodes ({scenes}), "
        f"both agents on the same observations, same actions; {wall:.0f} s in all"
    )
    print(f"{'ms per step':>12} {'reference':>10} {'fast':>8} {'ratio':>7}")
    results: dict[str, float] = {"steps": float(steps)}
    for part in (*PARTS, "total"):
        before = _ms(reference, part)
        after = _ms(fast, part)
        results[f"reference_{part}_ms"], results[f"fast_{part}_ms"] = before, after
        results[f"ratio_{part}"] = before / after if after > 0 else float("inf")
        target = f"   (target ≥ {TARGET:.0f})" if part == "total" else ""
        print(f"{part:>12} {before:>10.2f} {after:>8.2f} {before / after:>6.2f}×{target}")
    return results


def _ms(times: StepTimes, part: str) -> float:
    seconds: float = (
        sum(getattr(times, p) for p in PARTS) if part == "total" else getattr(times, part)
    )
    return 1000.0 * seconds / max(1, times.steps)


def _share(thinking_ms: float, env_ms: float) -> str:
    return f"{100.0 * thinking_ms / (thinking_ms + env_ms):.0f}%"


def _load(load: tuple[float, float, float]) -> str:
    return ", ".join(f"{v:.2f}" for v in load)
