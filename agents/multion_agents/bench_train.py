"""``multion bench --only train``: what learning costs on top of simulation, measured in one run.

Both measurements use the same environments (same model sensors, image size, number of
environments in local simulator processes, and the packaged 1-ON val episodes, which are grouped
by scene so scene loading hardly counts):

1. **bare**: the vector env stepped with uniformly random actions (simulation only), which is
   what the freshly initialised policy of the timed updates does too;
2. **train**: ``multion train`` updates (simulation + policy inference + PPO updates); the first
   update is a warm-up and is not counted.

It prints both rates, their ratio and the training overhead ``bare / train - 1`` (issue target:
at most 30%), with the time split between simulation, acting and updating.
"""

from __future__ import annotations

import csv
import tempfile
import time
from pathlib import Path

import numpy as np

TARGET_OVERHEAD = 0.3
"""The issue's target: learning costs at most 30% on top of simulation."""


def bare_rate(config: dict, envs: int, steps: int) -> float:
    """Vector-env steps per second (frames) with random actions."""
    from multion_agents.learned.rollout_envs import make_vector_env

    vector = make_vector_env(config, envs)
    try:
        vector.reset(seed=0)
        rng = np.random.default_rng(0)
        for _ in range(10):  # warm-up: workers started, scenes loaded
            vector.step(rng.integers(1, 4, envs))
        tick = time.perf_counter()
        for _ in range(steps):
            # uniform over the 4 actions, like the untrained policy the timed updates start
            # from: as many wrong FOUNDs, hence episode resets, in both measurements
            vector.step(rng.integers(0, 4, envs))
        return steps * envs / (time.perf_counter() - tick)
    finally:
        vector.close()


def run_train_bench(
    agent: str = "oracle-map", image_size: int = 64, envs: int = 4, updates: int = 4
) -> dict[str, float]:
    from multion.task.dataset import packaged_dataset_path
    from multion_agents.learned.models import model_spec
    from multion_agents.learned.ppo import Args, train
    from multion_agents.learned.rollout_envs import training_env_config

    dataset = str(packaged_dataset_path(1, "val"))
    spec = model_spec(agent)
    config = training_env_config(
        1, spec.train_sensors, image_size, "val", spec.config_overrides, None, dataset
    )
    rollout_steps = 128
    print(
        f"training bench: {agent}, 1-ON, {image_size}² RGB-D, {envs} local envs, {updates} updates of {rollout_steps} steps"
    )
    bare = bare_rate(config, envs, steps=rollout_steps * max(1, updates - 1))
    with tempfile.TemporaryDirectory() as out:
        train(
            Args(
                agent=agent,
                task="1-on",
                frames=updates * rollout_steps * envs,
                envs=envs,
                image_size=image_size,
                dataset=dataset,
                out=out,
                progress=False,
                tensorboard=False,
            )
        )
        rows = list(csv.DictReader((Path(out) / "progress.csv").open()))[1:]
    frames = sum(rollout_steps * envs for _ in rows)
    seconds = sum(rollout_steps * envs / float(r["fps"]) for r in rows)
    parts = {k: sum(float(r[f"{k}_seconds"]) for r in rows) for k in ("sim", "act", "update")}
    trained = frames / seconds
    result = {
        "bare_fps": bare,
        "train_fps": trained,
        "ratio": trained / bare,
        "overhead": bare / trained - 1,
        **{f"{k}_share": v / seconds for k, v in parts.items()},
    }
    print(f"  bare simulation      {bare:8.1f} frames/s")
    print(f"  training             {trained:8.1f} frames/s")
    print(
        f"  ratio train / bare   {result['ratio']:8.2f}   (overhead {100 * result['overhead']:.0f}%, target ≤ {100 * TARGET_OVERHEAD:.0f}%)"
    )
    print(
        "  training time split   "
        + ", ".join(f"{k} {100 * result[f'{k}_share']:.0f}%" for k in ("sim", "act", "update"))
    )
    learner_ms = 1000 * (parts["act"] + parts["update"]) / frames
    budget_ms = 1000 * TARGET_OVERHEAD / bare
    result["learner_ms_per_frame"] = learner_ms
    print(
        f"  learner time          {learner_ms:8.2f} ms/frame (acting + updating; the {100 * TARGET_OVERHEAD:.0f}% target "
        f"leaves {budget_ms:.2f} ms/frame)"
    )
    return result
