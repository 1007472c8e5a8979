"""Every ``bash`` block of docs/leaderboard.md, run as written, in a temporary directory.

The docs' own challenge file is used, made small (one-room houses, a 32×32 camera, a few
episodes). Each command line runs in bash with the environment the previous lines left (so the
``export`` lines of Serving reach the later blocks). Only what cannot run here is replaced:

* ``multion serve …`` (it serves until stopped) is started in the background, on 127.0.0.1 and
  a free port, with one simulator worker, and stopped at the end;
* ``https://challenge.example.org`` and ``http://localhost:8000`` become that server's URL;
* ``mlb_…`` becomes the token that the Serving block's ``team add`` printed, ``RUN_ID`` a run of
  that team.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import tomllib

from multion.api.local_server import free_port
from waiting import answers, wait_until

DOCS = Path(__file__).resolve().parents[2] / "docs" / "leaderboard.md"
BIN = Path(sys.executable).parent


def bash_blocks(text: str) -> list[list[str]]:
    """The command lines of each ```bash block (continuation lines joined, comments kept)."""
    blocks = []
    for body in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        joined = re.sub(r"\\\n\s*", "", body)
        blocks.append([line for line in joined.splitlines() if line.strip()])
    return blocks


def small_challenge(text: str) -> str:
    """The docs' challenge file, with small houses, camera, episode counts and step limits."""
    toml = re.search(r"```toml\n(.*?)```", text, flags=re.S)
    assert toml, "no challenge file in the docs"
    source = toml.group(1)
    tomllib.loads(source)  # the docs' file parses as it is
    source = re.sub(r"rooms = \[\d+, \d+\]", "rooms = [1, 1]", source)
    source = re.sub(r"camera = \{[^}]*\}", "camera = { width = 32, height = 32 }", source)
    source = re.sub(r"max_steps = \d+", "max_steps = 30", source)
    source = re.sub(r"episodes = \d+", "episodes = 2", source)
    source = re.sub(r"houses = \d+", "houses = 1", source)
    return source


class Shell:
    """Runs command lines one by one, carrying the environment from line to line."""

    def __init__(self, cwd: Path) -> None:
        self.cwd = cwd
        self.env = {
            "PATH": f"{BIN}:{os.environ['PATH']}",
            "HOME": str(cwd),
            "MULTION_LEADERBOARD_TOKEN_CACHE_S": "0",
            "MULTION_LEADERBOARD_PICTURE_INTERVAL_S": "0.5",
        }
        self.outputs: list[tuple[str, str]] = []

    def run(self, line: str) -> str:
        dump = self.cwd / ".env.out"
        script = f"set -euo pipefail\n{line}\nenv -0 > {dump}\n"
        done = subprocess.run(
            ["bash", "-c", script], cwd=self.cwd, env=self.env, capture_output=True, text=True,
            timeout=900,
        )  # fmt: skip
        assert done.returncode == 0, (
            f"`{line}` failed ({done.returncode}):\n{done.stdout}\n{done.stderr}"
        )
        self.env = dict(item.split("=", 1) for item in dump.read_text().split("\0") if "=" in item)
        self.outputs.append((line, done.stdout))
        return done.stdout


def test_every_command_block_of_the_guide_runs_as_written(tmp_path: Path) -> None:
    text = DOCS.read_text()
    blocks = bash_blocks(text)
    serving = next(b for b in blocks if any(line.startswith("multion serve") for line in b))
    participants = next(b for b in blocks if any("multion submit" in line for line in b))
    others = [b for b in blocks if b is not serving and b is not participants]
    assert len(blocks) >= 4 and others, "the guide's blocks moved: update this test"
    (tmp_path / "challenge.toml").write_text(small_challenge(text))
    shell = Shell(tmp_path)
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    server: subprocess.Popen[bytes] | None = None
    token = ""

    def substitute(line: str) -> str:
        line = line.replace("https://challenge.example.org", url)
        line = line.replace("http://localhost:8000", url)
        line = line.replace("mlb_…", token)
        if "RUN_ID" in line:
            runs = shell.run('multion leaderboard runs --team "Team Rocket"')
            line = line.replace("RUN_ID", runs.split()[0])
        return line

    try:
        for line in serving:  # first: it makes the database, the server and the token
            if line.startswith("multion serve"):
                command = line.split("#")[0].replace("--port 8000", f"--port {port}")
                command = command.replace("--workers 4", "--workers 1")
                command = command.replace("--host 0.0.0.0", "--host 127.0.0.1")
                server = subprocess.Popen(
                    ["bash", "-c", f"exec {command}"], cwd=tmp_path, env=shell.env,
                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                )  # fmt: skip
                _wait_ready(url, server)
                continue
            out = shell.run(line)
            if "team add" in line:
                token = out.strip().splitlines()[-1]
        assert token.startswith("mlb_") and server is not None
        for block in (participants, *others):
            for line in block:
                shell.run(substitute(line))
        # what the blocks were meant to do, did happen
        runs = shell.run("multion leaderboard runs")
        assert runs.count("Team Rocket") == 2 and runs.count("[baseline]") == 2
        assert "Explorer (ours)" in runs
        assert (tmp_path / "results.csv").read_text().count("\n") >= 3
        assert '"episode_records"' in (tmp_path / "results.json").read_text()
        replayed = next(out for line, out in shell.outputs if "leaderboard replay" in line)
        assert "identical to the stored records" in replayed
        assert (tmp_path / "results.db").is_file() and not (tmp_path / "leaderboard.db").exists()
    finally:
        if server is not None:
            server.terminate()
            server.wait(30)


def _wait_ready(url: str, server: subprocess.Popen[bytes], timeout_s: float = 120) -> None:
    wait_until(lambda: answers(url + "/leaderboard", server, "HEAD"), timeout=timeout_s,
               interval=0.2, message="the docs' `multion serve` to answer")  # fmt: skip
