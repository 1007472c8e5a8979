"""What can go stale in the Dockerfiles, checked everywhere without a Docker engine: every COPY
source exists and is not hidden by .dockerignore, and the agent image stays light. The images
are built and run by tests/docker/ (where Docker is installed; required in CI)."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCKERFILES = sorted((ROOT / "docker").glob("*.Dockerfile"))
LIGHT_MODULES = {"__future__", "os", "time", "numpy", "multion_client"}


def copy_sources(dockerfile: Path) -> list[str]:
    """Sources of the COPY instructions that read the build context (not ``--from`` stages)."""
    sources = []
    for line in dockerfile.read_text().splitlines():
        words = line.split("#", 1)[0].split()  # COPY lines here are single-line, unquoted
        if not words or words[0].upper() != "COPY":
            continue
        args = words[1:]
        if any(a.startswith("--from") for a in args):
            continue
        sources += [a for a in args[:-1] if not a.startswith("--")]
    return sources


def test_there_are_server_and_agent_dockerfiles() -> None:
    assert {d.name for d in DOCKERFILES} >= {"server.Dockerfile", "agent.Dockerfile"}


@pytest.mark.parametrize("dockerfile", DOCKERFILES, ids=lambda p: p.name)
def test_copy_sources_exist_and_are_not_ignored(dockerfile: Path) -> None:
    ignored = {
        line.strip()
        for line in (ROOT / ".dockerignore").read_text().splitlines()
        if line.strip() and not line.startswith("#")
    }
    sources = copy_sources(dockerfile)
    assert sources
    for source in sources:
        assert (ROOT / source).exists(), f"{dockerfile.name}: COPY {source} does not exist"
        assert Path(source).parts[0] not in ignored, f"{source} is in .dockerignore"


def test_the_agent_image_holds_only_the_client() -> None:
    sources = copy_sources(ROOT / "docker" / "agent.Dockerfile")
    assert "client" in [s.rstrip("/") for s in sources]
    assert not {"server", "agents", "pyproject.toml"} & {s.rstrip("/") for s in sources}
    script = ast.parse((ROOT / "docker" / "random_agent.py").read_text())
    imported = {
        (node.module if isinstance(node, ast.ImportFrom) else alias.name).split(".")[0]
        for node in ast.walk(script)
        if isinstance(node, (ast.Import, ast.ImportFrom))
        for alias in node.names
    }
    assert imported <= LIGHT_MODULES, f"the example agent imports {imported - LIGHT_MODULES}"


def test_the_server_image_installs_the_distributions_by_their_names() -> None:
    """The runtime stage installs the built wheels by distribution name: a stale name (the
    distribution was renamed to multion-pybullet) fails the build with "No matching
    distribution" only when the image is built."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:
        import tomli as tomllib
    names = {
        tomllib.loads((ROOT / path).read_text())["project"]["name"]
        for path in ("pyproject.toml", "client/pyproject.toml")
    }
    text = (ROOT / "docker" / "server.Dockerfile").read_text().replace("\\\n", " ")
    line = next(line for line in text.splitlines() if "--find-links /wheels" in line)
    args = line.split("--find-links /wheels", 1)[1].split("&&", 1)[0].split()
    installed = {arg.strip('"').split("[")[0] for arg in args}
    assert installed == names, f"server.Dockerfile installs {installed}, the project has {names}"
