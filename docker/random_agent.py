"""Example remote agent: random actions against a MultiON server, metrics from the server.

Environment: ``MULTION_SERVER`` (URL, default http://127.0.0.1:8000), ``MULTION_TASK`` (number
of goals, default 3), ``MULTION_EPISODES`` (default 3), ``MULTION_SEED`` (default 0).
Replace ``choose`` with your policy; it sees only the sensors asked for in ``CONFIG``.
"""

from __future__ import annotations

import os
import time

import numpy as np

from multion_client import RemoteEnv
from multion_client.errors import ServerUnavailable

SENSORS = ["goal"]  # add "rgb", "depth", "gps", "compass" … as your agent needs


def choose(observation: dict[str, np.ndarray], rng: np.random.Generator) -> int:
    """Mostly move (FOUND is rare: a wrong FOUND ends the episode)."""
    return int(rng.choice(4, p=[0.02, 0.5, 0.24, 0.24]))  # FOUND, FORWARD, LEFT, RIGHT


def wait_for(url: str, timeout_s: float = 120.0) -> None:
    """The server may still be starting (its workers import the simulator)."""
    from multion_client.client import Client

    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with Client(url) as client:
                client.health()
            return
        except ServerUnavailable:
            if time.monotonic() > deadline:
                raise
            time.sleep(2.0)


def main() -> None:
    url = os.environ.get("MULTION_SERVER", "http://127.0.0.1:8000")
    num_goals = int(os.environ.get("MULTION_TASK", "3"))
    episodes = int(os.environ.get("MULTION_EPISODES", "3"))
    rng = np.random.default_rng(int(os.environ.get("MULTION_SEED", "0")))
    wait_for(url)
    config = {"task": {"num_goals": num_goals}, "split": "val", "sensors": SENSORS}
    env = RemoteEnv(url, config=config)
    try:
        for index in range(episodes):
            obs, info = env.reset(options={"episode_index": index})
            done = False
            while not done:
                obs, reward, terminated, truncated, info = env.step(choose(obs, rng))
                done = terminated or truncated
            m = info["metrics"]
            print(
                f"episode {info.get('episode_id')}: success {m['success']:.0f} "
                f"progress {m['progress']:.2f} spl {m['spl']:.3f} steps {m['steps']} "
                f"({m['end_reason']})",
                flush=True,
            )
    finally:
        env.close()


if __name__ == "__main__":
    main()
