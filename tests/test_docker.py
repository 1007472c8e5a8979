"""The Dockerfiles cannot be built here (no Docker engine), so check what can go stale in them:
every COPY source exists and is not hidden by .dockerignore, and the agent image stays light."""

from __future__ import annotations

import ast
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
