"""Both distributions build as wheels that install and work in a fresh virtual environment.

The import names are ``multion`` / ``multion_agents`` and ``multion_client``; the distributions
are ``multion-pybullet`` and ``multion-client`` (``multion`` on the public index is an unrelated
project). The fresh venv takes the dependencies from the package index (or pip's cache).
"""

from __future__ import annotations

import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

CHECK_SERVER = """
import gymnasium as gym
from importlib import metadata
assert metadata.version("multion-pybullet") == metadata.version("multion-client") == "0.1.0"
# no `import multion` first: the "module:" prefix of the id imports it
env = gym.make("multion:MultiON/1-ON-v0", config=None)
config = env.unwrapped.config
env = gym.make("multion:MultiON/1-ON-v0", config=type(config)(
    camera=type(config.camera)(width=16, height=16), task=type(config.task)(num_goals=1)))
obs, info = env.reset(seed=0)  # the packaged val episodes are in the wheel
assert obs["rgb"].shape == (16, 16, 3) and info["scene_id"].startswith("house-"), info
print("ok")
"""

CHECK_CLIENT = """
import sys
from multion_client import RemoteEnv
assert not {"pybullet", "multion", "torch", "fastapi"} & set(sys.modules)
print("ok")
"""


def run(command: list[str], cwd: Path) -> str:
    result = subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, f"{command}\n{result.stdout}\n{result.stderr}"
    return result.stdout


@pytest.mark.slow
def test_wheels_install_and_run_in_a_fresh_venv(tmp_path: Path) -> None:
    wheels = tmp_path / "wheels"
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    run([*pip, "wheel", "--no-deps", "-w", str(wheels), str(ROOT / "client"), str(ROOT)], ROOT)
    built = sorted(p.name for p in wheels.glob("*.whl"))
    assert [name.split("-")[0] for name in built] == ["multion_client", "multion_pybullet"]

    client_env, server_env = tmp_path / "client-venv", tmp_path / "server-venv"
    for env in (client_env, server_env):
        venv.create(env, with_pip=True)
    fresh_pip = ["-m", "pip", "--disable-pip-version-check", "-q", "install"]
    client_wheel = next(wheels.glob("multion_client-*.whl"))
    run([str(client_env / "bin" / "python"), *fresh_pip, str(client_wheel)], tmp_path)
    assert "ok" in run([str(client_env / "bin" / "python"), "-c", CHECK_CLIENT], tmp_path)

    server_python = str(server_env / "bin" / "python")
    run([server_python, *fresh_pip, *map(str, sorted(wheels.glob("*.whl")))], tmp_path)
    assert "ok" in run([server_python, "-c", CHECK_SERVER], tmp_path)
    assert "serve" in run([str(server_env / "bin" / "multion"), "--help"], tmp_path)
