"""The client package stays light: no PyBullet, torch, FastAPI or server package in sight."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

SCRIPT = """
import sys
import multion_client
from multion_client import Client, RemoteEnv, RemoteVectorEnv
from multion_client.errors import ServerUnavailable

url = "http://127.0.0.1:{port}"
env = RemoteEnv(url, {{"camera": {{"width": 32, "height": 32}}}}, lazy=True, retries=0)
try:
    RemoteEnv(url, retries=0)
except ServerUnavailable as error:
    assert "127.0.0.1" in str(error), error
else:
    raise SystemExit("expected ServerUnavailable from a server that is not there")
try:
    Client(url, retries=1, backoff_s=0.01).health()
except ServerUnavailable:
    pass
env.close()
heavy = [m for m in ("pybullet", "torch", "fastapi", "starlette", "uvicorn", "multion")
         if m in sys.modules]
print("heavy:", heavy)
raise SystemExit(1 if heavy else 0)
"""


def _closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def test_client_imports_nothing_heavy(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-c", SCRIPT.format(port=_closed_port())],
        cwd=tmp_path,  # so that no source tree on the path can leak a package in
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "heavy: []" in result.stdout


FAILED_INIT = """
from multion_client import RemoteVectorEnv
from multion_client.errors import ServerUnavailable

for urls, error in (([], ValueError), (["http://127.0.0.1:{port}"], ServerUnavailable)):
    env = RemoteVectorEnv.__new__(RemoteVectorEnv)
    try:
        env.__init__(urls, 1, retries=0)
    except error:
        pass
    else:
        raise SystemExit(f"expected {{error.__name__}}")
    env.close()  # what Gymnasium 1.1's VectorEnv.__del__ does with it
print("closed")
"""


def test_a_vector_env_whose_init_failed_closes_quietly() -> None:
    # with Gymnasium 1.1 (the client's floor) __del__ calls close(), which raised
    # AttributeError when __init__ had failed before the clients were made
    result = subprocess.run(
        [sys.executable, "-c", FAILED_INIT.format(port=_closed_port())],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "closed" in result.stdout
