"""The lowest versions the two pyproject.toml files allow, installed for real.

* The server's ``GET /v1/spec`` with gymnasium 1.1.0 (the floor) in the same process as a
  ``SyncVectorEnv`` of the MultiON env: gymnasium before 1.4 writes its ``AutoresetMode`` enum
  into the env class's shared ``metadata``, which the spec used to copy (a 500).
* The light client with its dependencies at their floors (numpy, msgpack, gymnasium) in
  a fresh virtual environment, playing against a server started from this environment.

Both need the package index (``pip install``); they are slow-marked and take ~1 minute.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import venv
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from packaging.version import Version

from multion.api.local_server import LocalServer
from multion.config.episode import Episode

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ROOT = Path(__file__).resolve().parent.parent
pytestmark = pytest.mark.slow


def floors(pyproject: Path) -> dict[str, str]:
    """``{name: lowest version}`` of every ``name>=X`` dependency (extras and markers dropped)."""
    project = tomllib.loads(pyproject.read_text())["project"]
    lowest = {}
    for requirement in project["dependencies"]:
        spec = requirement.split(";")[0].replace(" ", "")
        if ">=" not in spec:
            continue
        name, rest = spec.split(">=", 1)
        lowest[name.split("[")[0]] = rest.split(",")[0]
    return lowest


CLIENT_FLOORS = floors(ROOT / "client" / "pyproject.toml")


def pip_install(python: Path | str, *args: str) -> None:
    subprocess.run(
        [str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check", *args],
        check=True,
        timeout=600,
    )


def test_the_client_floors_are_those_of_the_server() -> None:
    server = floors(ROOT / "pyproject.toml")
    for name in ("numpy", "gymnasium", "msgpack"):
        assert server[name] == CLIENT_FLOORS[name], name


SPEC_WITH_A_VECTOR_ENV = """
import gymnasium
from fastapi.testclient import TestClient
from gymnasium.vector import SyncVectorEnv

from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion.task.env import MultiONEnv
from multion_client.protocol import decode

print("gymnasium", gymnasium.__version__)
vector = SyncVectorEnv([MultiONEnv])  # before 1.4 this writes into MultiONEnv.metadata
with TestClient(create_app(ServerSettings(workers=1)), raise_server_exceptions=False) as api:
    response = api.get("/v1/spec")
    assert response.status_code == 200, (response.status_code, response.content[:300])
    spec = decode(response.content)
    assert spec["autoreset_mode"] == "same_step", spec["autoreset_mode"]
    assert spec["metadata"] == {"render_modes": ["rgb_array"], "render_fps": 10}, spec["metadata"]
vector.close()
print("spec ok")
"""


def test_spec_with_the_lowest_gymnasium_after_a_vector_env(tmp_path: Path) -> None:
    gymnasium_floor = CLIENT_FLOORS["gymnasium"]
    overlay = tmp_path / "overlay"
    pip_install(
        sys.executable, "--no-deps", "--target", str(overlay), f"gymnasium=={gymnasium_floor}"
    )
    env = dict(os.environ, PYTHONPATH=str(overlay))  # ahead of this venv's gymnasium
    result = subprocess.run(
        [sys.executable, "-c", SPEC_WITH_A_VECTOR_ENV],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert f"gymnasium {gymnasium_floor}" in result.stdout, result.stdout + result.stderr
    assert result.returncode == 0 and "spec ok" in result.stdout, result.stdout + result.stderr


CLIENT_SCRIPT = """
import json
import sys
import gymnasium, msgpack, numpy
from multion_client import RemoteEnv, RemoteVectorEnv

msgpack_version = ".".join(map(str, msgpack.version))
print("versions", numpy.__version__, msgpack_version, gymnasium.__version__)
url, config = sys.argv[1], json.loads(sys.argv[2])
env = RemoteEnv(url, config=config)
obs, info = env.reset(seed=0)
assert obs["rgb"].shape == (32, 32, 3) and env.observation_space.contains(obs)
for _ in range(4):
    obs, reward, terminated, truncated, info = env.step(1)
assert truncated and "spl" in info["metrics"], info
env.close()
vector = RemoteVectorEnv([url], 2, config=config)
obs, info = vector.reset(seed=[0, 1])
obs, reward, terminated, truncated, info = vector.step(numpy.array([2, 3]))
assert obs["rgb"].shape == (2, 32, 32, 3) and reward.shape == (2,)
vector.close()
print("client ok")
"""


@pytest.fixture(scope="module")
def server() -> Iterator[str]:
    with LocalServer(workers=1) as running:
        yield running.url


def test_the_light_client_at_its_floors(
    tmp_path: Path, server: str, room_episodes: Callable[[int, int, str], list[Episode]]
) -> None:
    config = {
        "camera": {"width": 32, "height": 32},
        "task": {"num_goals": 1, "max_steps": 4},
        "episodes": [e.to_dict() for e in room_episodes(2, 0, "floors")],
    }
    venv.create(tmp_path / "venv", with_pip=True)
    python = tmp_path / "venv" / "bin" / "python"
    pins = [f"{name}=={version}" for name, version in CLIENT_FLOORS.items()]
    pip_install(python, "--only-binary=:all:", *pins)
    pip_install(python, "--no-deps", str(ROOT / "client"))
    result = subprocess.run(
        [str(python), "-c", CLIENT_SCRIPT, server, json.dumps(config)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0 and "client ok" in result.stdout, result.stdout + result.stderr
    versions = result.stdout.split("versions ", 1)[1].split("\n", 1)[0].split()
    expected = [CLIENT_FLOORS[n] for n in ("numpy", "msgpack", "gymnasium")]
    assert [Version(v) for v in versions] == [Version(v) for v in expected]
