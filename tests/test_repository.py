"""The repository holds nothing that resolves only on one machine (issue 42: a committed link to
an absolute path broke the README's first command on every fresh clone)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def leaving_links(root: Path) -> list[str]:
    """Tracked symbolic links that are absolute or point outside ``root``, with their targets."""
    listing = subprocess.run(
        ["git", "ls-files", "-s", "-z"], cwd=root, capture_output=True, check=True, text=True
    ).stdout
    bad = []
    for entry in filter(None, listing.split("\0")):
        mode, _, _, path = entry.split(maxsplit=3)
        if mode != "120000":
            continue
        target = subprocess.run(
            ["git", "cat-file", "-p", f":{path}"],
            cwd=root,
            capture_output=True,
            check=True,
            text=True,
        ).stdout
        resolved = (root / path).parent / target
        if Path(target).is_absolute() or not resolved.resolve().is_relative_to(root.resolve()):
            bad.append(f"{path} -> {target}")
    return bad


def _git(root: Path, *argv: str) -> None:
    subprocess.run(["git", *argv], cwd=root, check=True, capture_output=True)


@pytest.mark.skipif(not (ROOT / ".git").exists(), reason="not a git checkout")
def test_no_tracked_link_leaves_the_repository() -> None:
    assert leaving_links(ROOT) == []


def test_the_check_finds_absolute_and_escaping_links_and_keeps_inner_ones(tmp_path: Path) -> None:
    _git(tmp_path, "init", "-q")
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text("a")
    (tmp_path / "runs").symlink_to("/somewhere/on/one/machine/runs")
    (tmp_path / "up").symlink_to("../outside")
    (tmp_path / "inner").symlink_to("docs/a.md")
    _git(tmp_path, "add", "-A")
    assert sorted(leaving_links(tmp_path)) == [
        "runs -> /somewhere/on/one/machine/runs",
        "up -> ../outside",
    ]
