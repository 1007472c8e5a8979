"""Issue 53 item 5: ``scripts/setup.sh`` printed about 20 lines of setuptools' "Editable
installation" warnings (one per editable package) among its output. The script silences that
warning alone, through ``PYTHONWARNINGS``: an editable build with its setting prints nothing,
and a failing install still prints pip's error."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SETUP = ROOT / "scripts" / "setup.sh"


def setup_warnings() -> str:
    """The ``PYTHONWARNINGS`` that setup.sh gives pip (with none set before it)."""
    found = re.search(r"^export PYTHONWARNINGS=(.+)$", SETUP.read_text(), re.MULTILINE)
    assert found, "setup.sh sets no PYTHONWARNINGS for pip"
    script = f'unset PYTHONWARNINGS; export PYTHONWARNINGS={found.group(1)}; echo "$PYTHONWARNINGS"'
    return subprocess.run(
        ["bash", "-c", script], capture_output=True, text=True, check=True
    ).stdout.strip()


PYPROJECT = """[build-system]
requires = ["setuptools>=64"]
build-backend = "setuptools.build_meta"

[project]
name = "multion-setup-probe"
version = "0.1"
"""


def probe_package(directory: Path) -> Path:
    """A one-module package laid out as ./client is (a package folder beside pyproject.toml):
    installing it touches nothing this venv holds."""
    (directory / "multion_setup_probe").mkdir(parents=True)
    (directory / "multion_setup_probe" / "__init__.py").write_text("")
    (directory / "pyproject.toml").write_text(PYPROJECT)
    return directory


def pip_install(
    target: Path, prefix: Path, warnings: str | None
) -> subprocess.CompletedProcess[str]:
    """``pip install -e target`` as setup.sh runs it (-q), into ``prefix`` (not this venv),
    offline, without dependencies, with this venv's setuptools."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    if warnings is not None:
        env["PYTHONWARNINGS"] = warnings
    command = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", "install",
               "--no-deps", "--no-build-isolation", "--no-index", "--prefix", str(prefix),
               "-e", str(target)]  # fmt: skip
    return subprocess.run(
        command, capture_output=True, text=True, env=env, cwd=target.parent, timeout=300
    )


def test_setup_silences_the_editable_install_warning_alone(tmp_path: Path) -> None:
    pytest.importorskip("setuptools", reason="the editable build needs setuptools in this venv")
    warnings = setup_warnings()
    assert warnings == "ignore:Editable installation"
    loud = pip_install(probe_package(tmp_path / "loud"), tmp_path / "loud-prefix", None)
    assert loud.returncode == 0, loud.stderr
    assert "Editable installation" in loud.stdout + loud.stderr  # what setup.sh printed
    quiet = pip_install(probe_package(tmp_path / "quiet"), tmp_path / "quiet-prefix", warnings)
    assert quiet.returncode == 0, quiet.stderr
    said = [
        line
        for line in (quiet.stdout + quiet.stderr).splitlines()
        if not line.startswith("WARNING: Location")
    ]  # fmt: skip  (a machine's pip config)
    assert said == []
    broken = pip_install(tmp_path / "no-such-package", tmp_path / "broken-prefix", warnings)
    assert broken.returncode != 0 and "ERROR" in broken.stderr  # errors still show
