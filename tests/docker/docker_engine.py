"""A private Docker daemon for the image and compose tests, and the stand-in base images.

The daemon runs in the background with its own data and exec roots under a temporary
directory, no iptables, no default bridge (compose makes its own networks) and a private socket
that ``DOCKER_HOST`` points at, so it never touches a Docker the machine may already run.

The official base images (``python:3.11-slim``, ``postgres:16``, ``nginx:1.27``) cannot be
pulled where these tests run, so stand-ins are built under those tags from a Debian bookworm
``debootstrap --variant=minbase`` tree and Debian's packages (``standins/*.Dockerfile``). The
project's Dockerfiles and compose files stay as a user runs them. Built stand-ins are saved to
a cache directory (``MULTION_DOCKER_CACHE``, default ``~/.cache/multion/docker``) and loaded
from there next time, keyed by a hash of their Dockerfiles.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from waiting import wait_until

HERE = Path(__file__).resolve().parent
STANDINS = HERE / "standins"
ROOT = HERE.parent.parent
# tag → Dockerfile in standins/
STANDIN_IMAGES = {
    "python:3.11-slim": "python.Dockerfile",
    "python:3.11-slim-bookworm": "python.Dockerfile",  # the server's: it pins Debian 12's Mesa
    "postgres:16": "postgres.Dockerfile",
    "nginx:1.27": "nginx.Dockerfile",
}
BASE_TAG = "multion-standin/bookworm"
SYSTEM_PARTS = "docker.io docker-compose debootstrap"
REQUIRE_DOCKER = "MULTION_REQUIRE_DOCKER"


def missing_tools() -> list[str]:
    """The commands these tests need that are not installed (empty when all are)."""
    tools = ["dockerd", "docker", "docker-compose", "debootstrap"]
    return [tool for tool in tools if shutil.which(tool) is None]


def cache_dir() -> Path:
    default = Path.home() / ".cache" / "multion" / "docker"
    path = Path(os.environ.get("MULTION_DOCKER_CACHE", default))
    path.mkdir(parents=True, exist_ok=True)
    return path


@dataclass
class Daemon:
    """A running private dockerd; ``env`` is the environment for docker and compose commands."""

    root: Path
    process: subprocess.Popen[bytes]
    env: dict[str, str]

    def run(
        self, *args: str, timeout: float = 600, check: bool = True, cwd: Path | None = None
    ) -> subprocess.CompletedProcess[str]:
        """Run a command (docker, docker-compose …) against this daemon, output captured."""
        result = subprocess.run(
            args, env=self.env, cwd=cwd, capture_output=True, text=True, timeout=timeout
        )
        if check and result.returncode != 0:
            raise AssertionError(
                f"{' '.join(args)} exited {result.returncode}\n"
                f"--- stdout\n{result.stdout[-4000:]}\n--- stderr\n{result.stderr[-4000:]}"
            )
        return result

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=60)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        # The daemon leaves mounts under its roots (the default network namespace at least).
        mounts = [line.split()[1] for line in Path("/proc/self/mounts").read_text().splitlines()]
        for mount in sorted((m for m in mounts if m.startswith(f"{self.root}/")), reverse=True):
            subprocess.run(["umount", "-l", mount], capture_output=True)
        shutil.rmtree(self.root, ignore_errors=True)


def start_daemon() -> Daemon:
    """Start dockerd in the background and wait (up to 60 s) until it answers."""
    # A short path: a unix socket's path must stay under 108 bytes.
    root = Path(tempfile.mkdtemp(prefix="mdock-"))
    socket = root / "docker.sock"
    log = (root / "dockerd.log").open("wb")
    process = subprocess.Popen(
        [
            "dockerd",
            f"--data-root={root / 'data'}",
            f"--exec-root={root / 'exec'}",
            f"--pidfile={root / 'dockerd.pid'}",
            f"--host=unix://{socket}",
            "--iptables=false",
            "--ip-masq=false",
            "--bridge=none",
        ],
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    # The classic builder: Debian's docker.io has no buildx, which BuildKit needs.
    env = dict(os.environ, DOCKER_HOST=f"unix://{socket}", DOCKER_BUILDKIT="0")
    # compose v1's `exec` and `run` through the Docker API, not by calling the docker CLI
    env["COMPOSE_INTERACTIVE_NO_CLI"] = "1"
    daemon = Daemon(root=root, process=process, env=env)

    def answering_or_gone() -> bool:
        return process.poll() is not None or (
            daemon.run("docker", "version", check=False, timeout=30).returncode == 0
        )

    try:
        wait_until(answering_or_gone, timeout=60, interval=0.5, message="dockerd to answer")
        assert process.poll() is None, f"dockerd exited with {process.returncode}"
    except AssertionError as error:
        text = (root / "dockerd.log").read_text(errors="replace")[-3000:]
        daemon.stop()
        raise RuntimeError(f"dockerd did not start ({error}):\n{text}") from None
    return daemon


def standins_key() -> str:
    """A hash of everything the stand-ins are built from, and of their tags."""
    digest = hashlib.sha256(repr(sorted(STANDIN_IMAGES.items())).encode())
    for path in sorted(STANDINS.iterdir()):
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def debootstrap_base(cache: Path) -> Path:
    """A bookworm minbase root file system as a tarball, made once and kept in the cache."""
    tarball = cache / "bookworm-minbase.tar"
    if tarball.exists():
        return tarball
    with tempfile.TemporaryDirectory(prefix="debootstrap-") as tmp:
        target = Path(tmp) / "rootfs"
        subprocess.run(
            [
                "debootstrap",
                "--variant=minbase",
                "bookworm",
                str(target),
                "http://deb.debian.org/debian",
            ],
            check=True,
            capture_output=True,
            timeout=1200,
        )
        # No caches or logs in the image; apt inside builds fetches its own lists.
        for junk in ("var/cache/apt/archives", "var/lib/apt/lists"):
            for entry in (target / junk).glob("*.deb"):
                entry.unlink()
        partial = tarball.with_suffix(".tar.partial")
        subprocess.run(["tar", "-C", str(target), "-cf", str(partial), "."], check=True)
        partial.rename(tarball)
    return tarball


def ensure_standins(daemon: Daemon) -> dict[str, float]:
    """Make the stand-in images exist in ``daemon``; returns seconds spent per step."""
    timings: dict[str, float] = {}
    cache = cache_dir()
    saved = cache / f"standins-{standins_key()}.tar"
    started = time.monotonic()
    if saved.exists():
        daemon.run("docker", "load", "-i", str(saved))
        timings["load cached stand-ins"] = time.monotonic() - started
        return timings
    tarball = debootstrap_base(cache)
    timings["debootstrap (or its cache)"] = time.monotonic() - started
    started = time.monotonic()
    daemon.run("docker", "import", str(tarball), BASE_TAG)
    with tempfile.TemporaryDirectory(prefix="standins-") as tmp:
        context = Path(tmp)
        for path in STANDINS.iterdir():
            shutil.copy2(path, context / path.name)
        shutil.copy2("/etc/ssl/certs/ca-certificates.crt", context / "ca-certificates.crt")
        for tag, dockerfile in STANDIN_IMAGES.items():
            daemon.run(
                "docker",
                "build",
                "--network",
                "host",
                "-q",
                "-f",
                str(context / dockerfile),
                "-t",
                tag,
                str(context),
                timeout=1200,
            )
    timings["build stand-ins"] = time.monotonic() - started
    started = time.monotonic()
    for old in cache.glob("standins-*.tar"):
        old.unlink()
    partial = saved.with_suffix(".partial")
    daemon.run("docker", "save", "-o", str(partial), *STANDIN_IMAGES)
    partial.rename(saved)
    timings["save stand-ins to the cache"] = time.monotonic() - started
    return timings
