"""The repository holds nothing that resolves only on one machine (issue 42: a committed link to
an absolute path broke the README's first command on every fresh clone)."""

from __future__ import annotations

import json
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


def absolute_checkpoints(root: Path) -> list[str]:
    """Published evaluation runs (``metrics.json`` under ``docs/``) whose checkpoint is recorded
    by an absolute path: a path of the machine that made them."""
    return [
        f"{path.relative_to(root)}: {checkpoint}"
        for path in sorted((root / "docs").rglob("metrics.json"))
        if (checkpoint := json.loads(path.read_text()).get("run", {}).get("checkpoint"))
        and Path(checkpoint).is_absolute()
    ]


def test_no_published_run_names_a_path_of_its_machine() -> None:
    assert absolute_checkpoints(ROOT) == []


def test_publishing_keeps_a_checkpoint_path_from_runs_on(tmp_path: Path) -> None:
    """scripts/publish_run.sh, which both comparison scripts publish with, on a run evaluated
    from a worktree with an absolute OUT."""
    run = tmp_path / "abs" / "runs" / "pilot" / "x" / "eval-val"
    run.mkdir(parents=True)
    metrics = {"run": {"checkpoint": f"{tmp_path}/abs/runs/pilot/x/checkpoint.pt", "seed": 0}}
    (run / "metrics.json").write_text(json.dumps(metrics))
    (run / "episodes.jsonl").write_text("{}\n")
    (run.parent / "progress.csv").write_text("update\n")
    kept = tmp_path / "docs" / "x"
    subprocess.run(
        ["bash", "-c", f'source {ROOT}/scripts/publish_run.sh && publish_run "$0" "$1"', run, kept],
        check=True,
    )
    assert sorted(p.name for p in kept.iterdir()) == [
        "episodes.jsonl",
        "metrics.json",
        "progress.csv",
    ]
    recorded = json.loads((kept / "metrics.json").read_text())["run"]
    assert recorded == {"checkpoint": "runs/pilot/x/checkpoint.pt", "seed": 0}
    assert absolute_checkpoints(tmp_path) == []
    (kept / "metrics.json").write_text(json.dumps(metrics))
    assert absolute_checkpoints(tmp_path) == [
        f"docs/x/metrics.json: {metrics['run']['checkpoint']}"
    ]
