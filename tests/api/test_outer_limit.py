"""Under an outer address-space limit (``ulimit -v``, ``prlimit --as``) below the default
``--worker-memory-mb``, the server takes the lower limit and says so, or refuses clearly."""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
from typing import Any

import pytest

from multion.api.local_server import free_port
from multion.api.settings import ServerSettings, fit_outer_memory_limit
from multion_client.client import Client
from multion_client.protocol import HEALTH_PATH
from waiting import answers, wait_until

OUTER_BYTES = 3 * 2**30
OPTION = "--worker-memory-mb"


def test_the_default_is_lowered_to_the_outer_limit_with_a_warning() -> None:
    settings, warning = fit_outer_memory_limit(ServerSettings(), OUTER_BYTES)
    assert settings.worker_memory_mb == 3072
    assert warning is not None and OPTION in warning and "3072 MiB" in warning
    # no outer limit, or one above the value: nothing changes, nothing to say
    for outer in (None, 16 * 2**30):
        unchanged, nothing = fit_outer_memory_limit(ServerSettings(), outer)
        if outer is None and unchanged.worker_memory_mb != 8192:  # this process has one
            continue
        assert unchanged.worker_memory_mb == 8192 and nothing is None


def test_a_value_given_above_the_outer_limit_or_a_tiny_limit_is_refused() -> None:
    with pytest.raises(ValueError, match=f"{OPTION}.*8192 MiB, above .* 3072 MiB"):
        fit_outer_memory_limit(ServerSettings(worker_memory_mb=8192), OUTER_BYTES)
    fitted, warning = fit_outer_memory_limit(ServerSettings(worker_memory_mb=2048), OUTER_BYTES)
    assert fitted.worker_memory_mb == 2048 and warning is None
    with pytest.raises(ValueError, match=f"512 MiB, below the 1024 MiB .*{OPTION}"):
        fit_outer_memory_limit(ServerSettings(), 512 * 2**20)


def _under_limit(limit_bytes: int, *options: str) -> subprocess.Popen[str]:
    """``multion serve`` under ``prlimit --as`` (or the same rlimit set before exec)."""
    command = [sys.executable, "-m", "multion_agents.cli", "serve", "--log-level", "warning",
               "--no-access-log", *options]  # fmt: skip
    preexec: Any = None
    if shutil.which("prlimit"):
        command = ["prlimit", f"--as={limit_bytes}", "--", *command]
    else:

        def preexec() -> None:
            resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))

    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=preexec,
    )  # fmt: skip


def test_serve_starts_under_prlimit_and_its_workers_step(small_config: dict[str, Any]) -> None:
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    process = _under_limit(OUTER_BYTES, "--port", str(port))
    try:
        wait_until(lambda: answers(url + HEALTH_PATH, process), timeout=90, interval=0.2,
                   message="the server to answer under prlimit")  # fmt: skip
        client = Client(url)
        try:
            session = client.create_session(small_config)  # a worker really runs
            client.reset(session.session_id)
            client.step(session.session_id, [1])
            client.close_session(session.session_id)
        finally:
            client.close()
    finally:
        process.terminate()
        _, err = process.communicate(timeout=60)
    assert "warning: this process's address-space limit (ulimit -v / prlimit --as)" in err
    assert "is 3072 MiB" in err
    assert OPTION in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("limit_bytes", "options", "expected"),
    [
        (OUTER_BYTES, (OPTION, "8192"), "is 8192 MiB, above this process's address-space limit"),
        (900 * 2**20, (), "is 900 MiB, below the 1024 MiB a simulator worker needs"),
    ],
)
def test_serve_refuses_what_cannot_fit_without_a_traceback(
    limit_bytes: int, options: tuple[str, ...], expected: str
) -> None:
    process = _under_limit(limit_bytes, "--port", str(free_port()), *options)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 2, err
    assert expected in err and OPTION in err and "Traceback" not in err
