"""The light paths stay light: the config package and ``multion --help`` load neither PyBullet
nor torch (nor FastAPI for the configs), so agents and tools can read configs cheaply."""

from __future__ import annotations

import subprocess
import sys

HEAVY = ("pybullet", "torch")


def loaded_after(code: str) -> set[str]:
    """The top-level modules loaded in a fresh interpreter after running ``code``."""
    probe = f"{code}\nimport sys\nprint(' '.join(sorted({{m.split('.')[0] for m in sys.modules}})))"
    result = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    return set(result.stdout.split("\n")[-2].split())


def test_the_config_package_loads_no_simulator_torch_or_web_framework() -> None:
    loaded = loaded_after(
        "import multion.config, multion.config.codec, multion.config.episode, "
        "multion.config.ranges, multion.config.scenes, multion.config.sim, multion.config.task\n"
        "multion.config.codec.env_config_from_dict({'camera': {'width': 64}})"
    )
    assert not {*HEAVY, "fastapi", "scipy"} & loaded


def test_multion_help_loads_no_simulator_or_torch() -> None:
    loaded = loaded_after(
        "import contextlib, io\n"
        "from multion_agents.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    assert main([]) == 2"
    )
    assert "multion_agents" in loaded
    assert not set(HEAVY) & loaded
