"""The commands catch UsageError only (issue 45 item 2): the user's mistake is a one-line
message and exit status 2; a builtin raised by a bug (numpy, torch, ours) keeps its traceback."""

from __future__ import annotations

import importlib
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from multion_agents.cli import main

BUG = "operands could not be broadcast together with shapes (4,) (5,)"

# Where `multion train` finds the training loop: ppo.train, moving to training_run.train
# (issue 45 item 3); each of these that exists is replaced.
TRAIN_MODULES = ("multion_agents.learned.ppo", "multion_agents.learned.training_run")

# `multion ARGS` in a fresh process, with the training loop replaced by one that hits a bug
TRAIN_WITH_A_BUG = f"""
import importlib, sys

def train(*args, **kwargs):
    raise ValueError({BUG!r})

for name in {TRAIN_MODULES!r}:
    try:
        module = importlib.import_module(name)
    except ImportError:
        continue
    if hasattr(module, "train"):
        module.train = train
from multion_agents.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _replace_training(monkeypatch: pytest.MonkeyPatch, train: Callable[..., None]) -> None:
    for name in TRAIN_MODULES:
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        monkeypatch.setattr(module, "train", train, raising=False)


def test_a_bug_in_training_exits_with_its_traceback(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    out = tmp_path / "run"
    result = subprocess.run(
        [sys.executable, "-c", TRAIN_WITH_A_BUG, "train", "--frames", "64", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode not in (0, 2), result.stderr
    assert "Traceback (most recent call last)" in result.stderr
    assert f"ValueError: {BUG}" in result.stderr
    assert "multion train:" not in result.stderr


@pytest.mark.parametrize("builtin", [ValueError, RuntimeError, TypeError])
def test_train_and_eval_let_builtins_through(
    builtin: type[Exception], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("torch")
    import multion_agents.evaluate

    def buggy(*args: object, **kwargs: object) -> None:
        raise builtin(BUG)

    _replace_training(monkeypatch, buggy)
    monkeypatch.setattr(multion_agents.evaluate, "evaluate", buggy)
    with pytest.raises(builtin, match="could not be broadcast"):
        main(["train", "--frames", "64", "--out", str(tmp_path / "run")])
    with pytest.raises(builtin, match="could not be broadcast"):
        main(["eval", "--agent", "random", "--episodes", "1", "--quiet"])


def test_usage_errors_exit_2_with_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("torch")
    from multion_agents.learned.checkpoint import CheckpointError

    out = str(tmp_path / "run")
    assert main(["train", "--gamma", "2", "--frames", "64", "--out", out]) == 2
    assert capsys.readouterr().err == "multion train: --gamma must be in [0, 1], got 2.0\n"

    def bad_checkpoint(*args: object, **kwargs: object) -> None:
        raise CheckpointError("run/checkpoint.pt: not a MultiON checkpoint")

    _replace_training(monkeypatch, bad_checkpoint)
    assert main(["train", "--frames", "64", "--out", out]) == 2
    err = capsys.readouterr().err
    assert err == "multion train: run/checkpoint.pt: not a MultiON checkpoint\n"
    assert main(["eval", "--agent", "random", "--split", "nowhere", "--quiet"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        "multion eval: unknown split 'nowhere'; splits are " + _splits()
    ]


def _splits() -> str:
    from multion_agents.eval_settings import SPLITS

    return ", ".join(SPLITS)
