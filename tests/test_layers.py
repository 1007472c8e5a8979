"""The import-linter contracts of ``pyproject.toml`` hold (issue 32): the layers
``multion_agents`` > ``multion.leaderboard`` > ``multion.api`` > ``multion.task`` >
``multion.sim`` > ``multion.scenes`` > ``multion.config``, a client that imports no server code,
light configs, and no import cycles between sibling modules."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_import_contracts_are_kept() -> None:
    sources = [str(ROOT / part) for part in ("server", "client", "agents")]
    path = os.pathsep.join([*sources, os.environ.get("PYTHONPATH", "")])
    result = subprocess.run(
        [str(Path(sys.executable).with_name("lint-imports")), "--no-cache"],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": path},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout
