"""Start a MultiON server in a subprocess on a free loopback port (for tests and benchmarks)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from types import TracebackType

import httpx

from multion.common.processes import die_with_parent
from multion.config.errors import UsageError
from multion_client.protocol import HEALTH_PATH


def free_port(host: str = "127.0.0.1") -> int:
    """A port nobody listens on right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


class LocalServerError(UsageError, RuntimeError):
    """The local server did not start (its output says why: a port in use, a bad option)."""


class LocalServer:
    """``with LocalServer(workers=2) as server: ... server.url ...``; always stopped on exit.

    ``options`` are extra ``multion serve`` arguments, e.g. ``["--idle-timeout-s", "5"]``.
    ``serve_module`` is the module run with ``python -m``: the plain session server, or
    ``multion.leaderboard.cli_serve.SERVE_MODULE`` for ``--challenge`` (this layer does not
    know the leaderboard).
    """

    def __init__(
        self,
        workers: int = 1,
        options: list[str] | None = None,
        start_timeout_s: float = 60.0,
        serve_module: str = "multion.api.cli_serve",
    ) -> None:
        self.host, self.port = "127.0.0.1", free_port()
        self.url = f"http://{self.host}:{self.port}"
        self.command = [
            sys.executable,
            "-m",
            serve_module,
            "--host",
            self.host,
            "--port",
            str(self.port),
            "--workers",
            str(workers),
            "--log-level",
            "warning",
            "--no-access-log",
            *(options or []),
        ]
        self.start_timeout_s = start_timeout_s
        self.process: subprocess.Popen[bytes] | None = None

    @property
    def pid(self) -> int:
        assert self.process is not None
        return self.process.pid

    def start(self) -> LocalServer:
        """Launch the server and wait until it answers."""
        return self.launch().wait_ready()

    def launch(self) -> LocalServer:
        """Launch the server without waiting (start several, then ``wait_ready`` on each)."""
        self.process = subprocess.Popen(
            self.command,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
            preexec_fn=die_with_parent,  # no orphan server if this process is killed
        )
        return self

    def wait_ready(self) -> LocalServer:
        assert self.process is not None, "launch() first"
        deadline = time.monotonic() + self.start_timeout_s
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                raise LocalServerError(
                    f"server exited with {self.process.returncode}: {self.command}"
                )
            try:
                if httpx.get(self.url + HEALTH_PATH, timeout=1.0).status_code == 200:
                    return self
            except httpx.TransportError:
                pass
            time.sleep(0.1)
        self.stop()
        raise LocalServerError(
            f"server did not answer within {self.start_timeout_s} s: {self.command}"
        )

    def stop(self, timeout_s: float = 15.0) -> None:
        if self.process is None or self.process.poll() is not None:
            return
        self.process.send_signal(signal.SIGINT)  # uvicorn's graceful shutdown stops the workers
        try:
            self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()

    def __enter__(self) -> LocalServer:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
