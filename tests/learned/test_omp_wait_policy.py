"""torch's OpenMP threads wait passively unless the user says otherwise (issue 44): spinning
threads made a PPO update 10x slower where simulators or other jobs share the cores."""

from __future__ import annotations

import os
import subprocess
import sys

PROBE = "import multion_agents, os, torch; print(os.environ.get('OMP_WAIT_POLICY'))"


def policy_seen(environment: dict[str, str]) -> str:
    result = subprocess.run(
        [sys.executable, "-c", PROBE], env=environment, capture_output=True, text=True, check=True
    )
    return result.stdout.strip()


def test_importing_the_agents_makes_openmp_threads_wait_passively() -> None:
    environment = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    assert policy_seen(environment) == "PASSIVE"


def test_a_wait_policy_the_user_set_is_kept() -> None:
    assert policy_seen({**os.environ, "OMP_WAIT_POLICY": "ACTIVE"}) == "ACTIVE"
