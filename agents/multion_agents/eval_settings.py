"""What ``multion eval`` evaluates, and where (``EvalSettings``): each field's default, range and
command-line option in one place (``multion_agents.cli_fields``)."""

from __future__ import annotations

from dataclasses import dataclass

from multion.config.datasets import parse_task
from multion.config.ranges import ConfigError
from multion_agents.agent import ConfigOverrides
from multion_agents.cli_fields import Option, check_settings, setting
from multion_agents.config_overrides import parse_env_overrides
from multion_client.constants import NUM_CATEGORIES

SPLITS = ("val", "test", "train")
DEFAULT_SPLIT = "val"


@dataclass(frozen=True)
class EvalSettings:
    """What to evaluate, and where."""

    agent: str = setting(
        cli=Option(
            "random, random-oracle-found, oracle-planner, explorer, or an import path "
            "'package.module:ClassName' of an Agent subclass"
        )
    )
    num_goals: int = setting(
        3,
        low=1,
        high=NUM_CATEGORIES,
        cli=Option("1-on … 8-on (default 3-on)", flag="--task", metavar="TASK", parse=parse_task),
    )
    split: str | None = setting(
        None,
        cli=Option("dataset split: val or test (default val; with --dataset, the one it holds)"),
    )
    """One of ``SPLITS``; any name goes with ``dataset``. None: ``DEFAULT_SPLIT``, or the split a
    ``dataset`` file names (:func:`multion_agents.evaluate.with_played_split`)."""
    episodes: int | None = setting(
        None,
        low=1,
        integer=True,
        cli=Option("evaluate N evenly spaced episodes (default all)"),
    )
    """How many episodes (evenly spaced over the dataset); None: all of them."""
    seed: int = setting(0, cli=Option("agent seed (default 0)"))
    server: str | None = setting(
        None, cli=Option("server URL, e.g. http://host:8000 (default: start one)")
    )
    """A server URL; None starts a local one."""
    in_process: bool = setting(
        False,
        cli=Option("no server: simulate in this process (to debug or profile an agent)"),
    )
    """Simulate in this process, without any server (for debugging and profiling agents)."""
    workers: int = setting(1, low=1, cli=Option("episodes played in parallel (default 1)"))
    dataset: str | None = setting(None, cli=Option("a dataset file instead of the packaged one"))
    image_size: int | None = setting(
        None,
        low=1,
        integer=True,
        cli=Option("camera width = height in pixels (default: the server's, 256 as in the paper)"),
    )
    """Camera width and height; None keeps the server's default (256, as in the paper)."""
    max_steps: int | None = setting(
        None,
        low=1,
        integer=True,
        cli=Option("step limit per episode (default 2500)"),
    )
    """Step limit override (None: the task's 2500); for quick checks only."""
    checkpoint: str | None = setting(
        None,
        cli=Option(
            "checkpoint of a learned agent (multion train), e.g. --agent oracle-map "
            "--checkpoint runs/om/checkpoint.pt"
        ),
    )
    """A training checkpoint of the learned agent ``agent`` (``multion train``)."""
    deterministic: bool = setting(
        False,
        cli=Option("learned agents take the most likely action instead of sampling"),
    )
    found_gate: float | None = setting(
        None,
        low=0.0,
        high=1.0,
        low_open=True,
        high_open=True,
        cli=Option(
            "learned agents trained with --found-head: call FOUND where the head's probability "
            "exceeds this (default 0.5; `multion diagnose` reads lower gates off played episodes)"
        ),
    )
    """The FOUND head's gate (``RecurrentPolicy.found_gate``); None: the policy's own."""
    env_overrides: ConfigOverrides = setting(
        default_factory=dict,
        cli=Option(
            "change the environment config, e.g. --set task.found_budget=3 "
            "--set maps.ego_size=25 --set camera.hfov_deg=90 (repeatable; values are JSON or "
            "strings; recorded in metrics.json)",
            flag="--set",
            metavar="SECTION.FIELD=VALUE",
            repeat=True,
            parse=parse_env_overrides,
        ),
    )
    """Environment config changes (``--set task.found_budget=3``), applied after the agent's."""

    def __post_init__(self) -> None:
        check_settings(self)
        if self.split is not None and self.split not in SPLITS and self.dataset is None:
            raise ConfigError(f"unknown split {self.split!r}; splits are {', '.join(SPLITS)}")
        if self.in_process and self.server is not None:
            raise ConfigError("--in-process and --server exclude each other")
