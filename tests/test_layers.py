"""The import-linter contracts of ``pyproject.toml`` hold (issues 32 and 45): the layers
``multion_agents`` > ``multion.leaderboard`` > ``multion.api`` > ``multion.video`` >
``multion.task`` > ``multion.sim`` > ``multion.scenes`` > ``multion.config`` > ``multion.common``
with every server module in one of them, a client that imports no server code, light configs, a
server process and settings that load no simulator, and no import cycles between siblings."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10
    import tomli as tomllib

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


def test_every_server_module_sits_in_a_layer() -> None:
    """A module outside the layers' list is checked by no layers contract: it could import
    anything, and anything could import it (issue 45 found seven such modules)."""
    with open(ROOT / "pyproject.toml", "rb") as handle:
        contracts = tomllib.load(handle)["tool"]["importlinter"]["contracts"]
    layers = next(c["layers"] for c in contracts if c["type"] == "layers")
    server = ROOT / "server"
    modules = [
        ".".join(path.relative_to(server).with_suffix("").parts).removesuffix(".__init__")
        for path in sorted((server / "multion").rglob("*.py"))
    ]
    outside = [
        name
        for name in modules
        if name != "multion"
        and not any(name == layer or name.startswith(layer + ".") for layer in layers)
    ]
    assert len(modules) > 100
    assert outside == [], f"modules in no layer of pyproject.toml's layers contract: {outside}"


def test_no_import_cycle_is_excused_and_training_never_imports_the_evaluator() -> None:
    """The trainer's periodic evaluation is passed in by ``multion train`` (issue 45 item 3):
    the cycle contract ignores no import, and no module of ``multion_agents.learned`` imports
    the evaluator, not even inside a function (import-linter sees those too, this says why)."""
    import ast

    with open(ROOT / "pyproject.toml", "rb") as handle:
        contracts = tomllib.load(handle)["tool"]["importlinter"]["contracts"]
    cycles = next(c for c in contracts if c["type"] == "acyclic_siblings")
    assert cycles.get("ignore_imports", []) == []
    reaching_up = []
    for path in sorted((ROOT / "agents" / "multion_agents" / "learned").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module == "multion_agents.evaluate":
                reaching_up.append(f"{path.name}:{node.lineno}")
    assert reaching_up == []
