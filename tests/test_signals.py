"""Every command that starts processes stops all of them on SIGTERM and on SIGINT.

SIGTERM is how ``timeout``, batch schedulers and container runtimes stop a program; before it
was handled, ``multion eval`` and ``multion bench`` left their servers and simulator workers
running as orphans. The signal goes to the command's own process only (the harder case: a
Ctrl-C in a terminal reaches the whole process group).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from multion.api.local_server import free_port
from process_tree import alive, descendants
from waiting import wait_until

MULTION = [sys.executable, "-m", "multion_agents.cli"]


def commands(tmp: Path) -> dict[str, tuple[list[str], int]]:
    """name → (arguments, how many descendants show that it is running)."""
    return {
        # the HTTP process's simulator workers (and multiprocessing's resource tracker)
        "serve": (["serve", "--port", str(free_port()), "--workers", "2"], 2),
        # a local server and its worker
        "eval": (
            ["eval", "--agent", "random", "--task", "1-on", "--episodes", "50", "--out", str(tmp)],
            2,
        ),
        # two local servers (one and two workers) of the vector-env measurement
        "bench": (["bench", "--only", "http", "--steps", "200"], 4),
        # the vector env's simulator processes
        "train": (
            [
                "train", "--agent", "no-map", "--frames", "100000", "--envs", "2",
                "--image-size", "36", "--out", str(tmp), "--no-tensorboard", "--quiet",
            ],
            2,
        ),
    }  # fmt: skip


def as_from_a_terminal() -> None:
    """Default SIGINT handling in the command, as a shell's foreground job has it. A test run
    started in the background (``.ci/run &``) ignores SIGINT, and its children inherit that."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
@pytest.mark.parametrize("name", ["serve", "eval", "bench", "train"])
def test_a_signal_stops_every_process_the_command_started(
    name: str, signum: int, tmp_path: Path
) -> None:
    if name == "train":
        pytest.importorskip("torch")
    arguments, running = commands(tmp_path)[name]
    process = subprocess.Popen(
        [*MULTION, *arguments], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        preexec_fn=as_from_a_terminal,
    )  # fmt: skip
    started: set[int] = set()
    try:

        def all_started() -> bool:
            assert process.poll() is None, f"multion {name} exited early"
            started.update(descendants(process.pid))
            return len(started) >= running

        wait_until(all_started, timeout=120, interval=0.2,
                   message=f"multion {name}'s {running} processes")  # fmt: skip
        time.sleep(1.0)  # let them get on with their work
        if name == "train":
            # into the rollouts: a signal there used to cut a worker's reply short, and close()
            # then waited for it forever (3 of 4 tries at 12-22 s)
            wait_until((tmp_path / "progress.csv").exists, timeout=120, interval=0.2,
                       message="the first rollout (progress.csv)")  # fmt: skip
            time.sleep(2.0)
        started |= descendants(process.pid)
        process.send_signal(signum)
        code = process.wait(timeout=60)
        assert code in (128 + signum, -signum, 130, 0), code
        with contextlib.suppress(AssertionError):  # the assertion below names those left
            wait_until(lambda: not alive(started), timeout=20, interval=0.2)
        assert not alive(started), f"multion {name} left {sorted(alive(started))} running"
    finally:
        for pid in alive(started | {process.pid}):
            os.kill(pid, signal.SIGKILL)
        process.wait(timeout=10)
