"""Reading ``multion eval`` output directories (``metrics.json`` + ``episodes.jsonl``) for reports.

A :class:`Run` is one agent on one task under one set of *conditions*: the things that must be
equal for two runs to be compared (split, dataset file, found budget, goal set, other ``--set``
changes, step limit, camera size). Runs written before ``multion eval`` recorded a field get its default;
a run without ``seed_scheme`` seeded its agents by episode index (:mod:`multion_agents.seeding`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from multion.config.datasets import parse_task
from multion.config.errors import UsageError
from multion.config.task import TaskConfig
from multion_agents.report.stats import HEADLINE
from multion_agents.seeding import OLD_SEED_SCHEME, SEED_SCHEMES, scheme_seed
from multion_client.constants import ACTIONS_TEXT, DEFAULT_GOAL_SET, Action

METRICS_FILE = "metrics.json"
EPISODES_FILE = "episodes.jsonl"
TRAINING_LOG = "progress.csv"
ACTION_DIGITS = "".join(str(int(action)) for action in Action)
"""The digits an ``episodes.jsonl`` writes its actions with (``evaluate.actions_text``)."""
DEFAULT_FOUND_BUDGET = TaskConfig().found_budget
DEFAULT_SUCCESS_DISTANCE = TaskConfig().success_distance


class RunError(UsageError, ValueError):
    """A directory that is not a readable ``multion eval`` run; the message names it."""


@dataclass(frozen=True)
class EpisodeResult:
    episode_id: str
    scene_id: str
    metrics: dict[str, Any]
    index: int = 0
    """The episode's position in the run's evaluated list (``index`` in ``episodes.jsonl``; its
    line number for runs without it): what the ``"index"`` seed scheme seeded from."""
    actions: str = ""
    """The actions taken, one digit each (0 FOUND, 1 forward, 2 left, 3 right); '' for runs
    written before ``episodes.jsonl`` kept them."""


@dataclass(frozen=True)
class Run:
    """One evaluation run, as read back from its directory."""

    path: Path
    agent: str
    num_goals: int
    split: str
    dataset: str
    """The dataset file's SHA-256 (12 hex digits), or its path for runs that predate it."""
    found_budget: int
    goal_set: str
    """``task.goal_set`` of the environment the agent played in (``colours``, ``shapes``, ...):
    the agent's own config (a checkpoint trained on shapes) or ``--set``."""
    settings: dict[str, str]
    """Everything else that changes the task, ``{"field": "value"}`` (``camera.width`` where
    ``--image-size`` was given, ``camera.renderer`` where set)."""
    camera_width: int
    """The images' width the agent saw, from the resolved config (a learned agent's is its
    checkpoint's, whether or not ``--image-size`` was given); 0 where no record says."""
    renderer: str
    """The renderer that drew them (``camera.renderer`` resolved; ``tiny`` for old runs)."""
    seed: int
    multion_version: str
    episodes: tuple[EpisodeResult, ...]
    checkpoint: str = ""
    """The learned agent's checkpoint (a run directory name), '' for the baselines."""
    training_log: Path | None = None
    """A learned agent's ``progress.csv`` (``multion train``), in the run directory or beside it
    (``multion train --out X`` then ``multion eval --out X/eval-val``), if there is one."""
    seed_scheme: str = OLD_SEED_SCHEME
    """How each episode's agent was seeded from :attr:`seed` (``run.seed_scheme``;
    ``"index"`` for runs written before the field)."""
    seed_scheme_recorded: bool = True
    """False for a run whose ``metrics.json`` has no ``seed_scheme`` (written before issue 53)."""
    agent_settings: str = ""
    """The agent's own tunables as ``name=value, ...`` (``found_gate=0.8``; ``run.agent_settings``),
    '' for agents without any."""
    success_distance: float = DEFAULT_SUCCESS_DISTANCE
    """``task.success_distance`` of the environment the agent played in, metres: how near a
    goal FOUND had to be called."""

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def agent_label(self) -> str:
        """The agent, with its checkpoint's run directory for learned agents."""
        return f"{self.agent} ({self.checkpoint})" if self.checkpoint else self.agent

    @property
    def label_besides_camera(self) -> str:
        """:attr:`agent_label` without the camera the checkpoint's run directory is named for:
        the scripts name a variant's run ``NAME-128``, ``NAME-gl`` or ``NAME-128-gl``, and that
        run varies ``NAME``'s camera only."""
        if not self.checkpoint:
            return self.agent
        name = self.checkpoint
        for suffix in (f"-{self.camera_width}-{self.renderer}", f"-{self.camera_width}",
                       f"-{self.renderer}"):  # fmt: skip
            if name.endswith(suffix):
                name = name.removesuffix(suffix)
                break
        return f"{self.agent} ({name})"

    @property
    def count(self) -> int:
        return len(self.episodes)

    def conditions(self) -> dict[str, str]:
        """What must match for runs to be compared (shown when it differs between runs)."""
        return {
            "split": self.split,
            "dataset": self.dataset,
            "found budget": str(self.found_budget),
            "goal set": self.goal_set,
            "settings": self.other_settings or "default",
        }

    @property
    def camera(self) -> str:
        """The camera, for tables: "36² (tiny)", "128² (gl)"."""
        return f"{self.camera_width or '?'}² ({self.renderer})"

    @property
    def other_settings(self) -> str:
        """:attr:`settings` as ``field=value, ...`` ('' when nothing)."""
        return _joined(self.settings)

    def conditions_besides_camera(self) -> dict[str, str]:
        """:meth:`conditions` with the camera's settings left out (runs that differ only in
        image size or renderer)."""
        others = {k: v for k, v in self.settings.items() if not k.startswith("camera.")}
        return {**self.conditions(), "settings": _joined(others) or "default"}

    def values(self, metric: str, episode_ids: Sequence[str] | None = None) -> np.ndarray:
        """Per-episode values of a metric, in episode order or in the order of ``episode_ids``."""
        if episode_ids is None:
            chosen = self.episodes
        else:
            by_id = {e.episode_id: e for e in self.episodes}
            chosen = tuple(by_id[i] for i in episode_ids)
        return np.array([float(e.metrics.get(metric, 0.0)) for e in chosen], dtype=np.float64)

    def episode_ids(self) -> list[str]:
        return [e.episode_id for e in self.episodes]

    @property
    def seeding(self) -> str:
        """The seed and its scheme, for tables: "0 (episode id)", "0 (index, unrecorded)"."""
        scheme = self.seed_scheme.replace("_", " ")
        return f"{self.seed} ({scheme}{'' if self.seed_scheme_recorded else ', unrecorded'})"

    def agent_seeds(self, episode_ids: Sequence[str]) -> list[int]:
        """The seed each of ``episode_ids`` gave its agent in this run."""
        by_id = {e.episode_id: e for e in self.episodes}
        return [scheme_seed(self.seed_scheme, self.seed, by_id[i].index, i) for i in episode_ids]


def seeding_difference(a: Run, b: Run, episode_ids: Sequence[str]) -> str | None:
    """Why the agents of ``a`` and ``b`` drew from different seeds on some of ``episode_ids``
    (the episodes both played), or None when every one was seeded alike. Runs of deterministic
    agents play the same whatever their seeds; the report cannot tell which agents are."""
    differing = sum(
        x != y for x, y in zip(a.agent_seeds(episode_ids), b.agent_seeds(episode_ids), strict=True)
    )
    if not differing:
        return None
    reasons = []
    if a.seed != b.seed:
        reasons.append(f"seeds {a.seed} and {b.seed}")
    if a.seed_scheme != b.seed_scheme:
        reasons.append(f"seed schemes {a.seeding} and {b.seeding}")
    elif a.seed_scheme == OLD_SEED_SCHEME and a.seed == b.seed:
        reasons.append("seeded by position in the list, and the episodes stand at other positions")
    return (
        f"{a.name} and {b.name} seeded their agents differently on {differing} of "
        f"{len(episode_ids)} shared episodes ({'; '.join(reasons)}): a stochastic agent drew "
        "other random numbers there."
    )


def expand_run_dirs(paths: Sequence[Path]) -> list[Path]:
    """Run directories among ``paths``: a path holding no run itself but run subdirectories
    (e.g. ``runs/baselines``) stands for all of them. Raises :class:`RunError` otherwise."""
    found: list[Path] = []
    for path in paths:
        if not path.is_dir():
            raise RunError(f"{path}: not a directory (give `multion eval --out` directories)")
        if (path / METRICS_FILE).exists() or (path / EPISODES_FILE).exists():
            found.append(path)
            continue
        children = sorted(p.parent for p in path.glob(f"*/{METRICS_FILE}"))
        if not children:
            raise RunError(
                f"{path}: no {METRICS_FILE} here or in its subdirectories "
                "(is this a `multion eval --out` directory?)"
            )
        found.extend(children)
    seen: set[Path] = set()
    for path in found:
        if path.resolve() in seen:
            raise RunError(f"{path}: given twice (each run may enter a report once)")
        seen.add(path.resolve())
    return found


def load_run(path: Path) -> Run:
    """Read one run directory; a :class:`RunError` says what is missing or malformed."""
    metrics_path, episodes_path = path / METRICS_FILE, path / EPISODES_FILE
    for required in (metrics_path, episodes_path):
        if not required.is_file():
            raise RunError(
                f"{path}: no {required.name} (is this a `multion eval --out` directory?)"
            )
    try:
        payload = json.loads(metrics_path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise RunError(f"{metrics_path}: not valid JSON ({error})") from None
    run = payload.get("run") if isinstance(payload, dict) else None
    if not isinstance(run, dict):
        raise RunError(f"{metrics_path}: no 'run' section (not written by `multion eval`?)")
    for key in ("agent", "task", "split"):
        if not isinstance(run.get(key), str):
            raise RunError(f"{metrics_path}: 'run.{key}' is missing or not a string")
    try:
        num_goals = parse_task(run["task"])
    except ValueError as error:
        raise RunError(f"{metrics_path}: {error}") from None
    episodes = _read_episodes(episodes_path, num_goals)
    scheme = run.get("seed_scheme", OLD_SEED_SCHEME)
    if scheme not in SEED_SCHEMES:
        raise RunError(
            f"{metrics_path}: 'run.seed_scheme' is {scheme!r}, not one of {', '.join(SEED_SCHEMES)}"
        )
    if isinstance(run.get("episodes"), int) and run["episodes"] != len(episodes):
        raise RunError(
            f"{path}: metrics.json says {run['episodes']} episodes but {EPISODES_FILE} has "
            f"{len(episodes)} (an interrupted or mixed-up run?)"
        )
    agent_settings = run.get("agent_settings") or {}
    if not isinstance(agent_settings, dict):
        raise RunError(f"{metrics_path}: 'run.agent_settings' is not an object")
    resolved = run.get("resolved_config") or {}
    task = {**(run.get("env_config") or {}).get("task", {}), **resolved.get("task", {})}
    camera = {**(run.get("env_config") or {}).get("camera", {}), **resolved.get("camera", {})}
    return Run(
        path=path,
        agent=run["agent"],
        num_goals=num_goals,
        split=run["split"],
        dataset=_dataset_label(run),
        found_budget=int(task.get("found_budget", DEFAULT_FOUND_BUDGET)),
        goal_set=str(task.get("goal_set", DEFAULT_GOAL_SET)),
        settings=_settings(run),
        camera_width=int(camera.get("width") or 0),
        renderer=str(camera.get("renderer") or "tiny"),
        seed=int(run.get("seed", 0)),
        multion_version=str((run.get("versions") or {}).get("multion", "unknown")),
        episodes=episodes,
        checkpoint=_checkpoint_label(run),
        training_log=_training_log(path) if run.get("checkpoint") else None,
        seed_scheme=str(scheme),
        seed_scheme_recorded="seed_scheme" in run,
        agent_settings=_joined({key: str(value) for key, value in agent_settings.items()}),
        success_distance=float(task.get("success_distance", DEFAULT_SUCCESS_DISTANCE)),
    )


def load_runs(paths: Sequence[Path]) -> list[Run]:
    """All runs under ``paths`` (see :func:`expand_run_dirs`), in the order given."""
    return [load_run(path) for path in expand_run_dirs(paths)]


def _read_episodes(path: Path, num_goals: int) -> tuple[EpisodeResult, ...]:
    episodes: list[EpisodeResult] = []
    seen: set[str] = set()
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError as error:
        raise RunError(f"{path}: not UTF-8 text ({error})") from None
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            item = json.loads(line)
        except json.JSONDecodeError as error:
            raise RunError(f"{path}, line {number}: not valid JSON ({error})") from None
        metrics = item.get("metrics") if isinstance(item, dict) else None
        if not isinstance(metrics, dict) or not isinstance(item.get("episode_id"), str):
            raise RunError(f"{path}, line {number}: expected an object with episode_id and metrics")
        missing = [key for key, _ in HEADLINE if not isinstance(metrics.get(key), (int, float))]
        if missing:
            raise RunError(f"{path}, line {number}: metrics lack {', '.join(missing)}")
        seen_flags = metrics.get("seen_before_current")
        if seen_flags is not None and len(seen_flags) != num_goals - 1:
            raise RunError(
                f"{path}, line {number}: seen_before_current has {len(seen_flags)} entries, "
                f"expected {num_goals - 1} for {num_goals} goals"
            )
        if item["episode_id"] in seen:
            raise RunError(f"{path}, line {number}: episode {item['episode_id']} appears twice")
        seen.add(item["episode_id"])
        index = item.get("index", len(episodes))
        if not isinstance(index, int):
            raise RunError(f"{path}, line {number}: index {index!r} is not an integer")
        actions = item.get("actions", "")
        if not isinstance(actions, str) or actions.strip(ACTION_DIGITS) != "":
            raise RunError(
                f"{path}, line {number}: actions must be a string of the digits "
                f"{ACTION_DIGITS[0]}-{ACTION_DIGITS[-1]} ({ACTIONS_TEXT})"
            )
        episodes.append(
            EpisodeResult(
                item["episode_id"], str(item.get("scene_id", "")), metrics, index, actions
            )
        )
    if not episodes:
        raise RunError(f"{path}: no episodes")
    return tuple(episodes)


def dataset_label(sha256: str) -> str:
    """How a run names its dataset file: the first 12 hex digits of its SHA-256."""
    return sha256[:12]


def _dataset_label(run: dict[str, Any]) -> str:
    if run.get("dataset_sha256"):
        return dataset_label(str(run["dataset_sha256"]))
    return str(run.get("dataset") or "packaged (no checksum recorded)")


def _checkpoint_label(run: dict[str, Any]) -> str:
    if not run.get("checkpoint"):
        return ""
    checkpoint = Path(str(run["checkpoint"]))
    label = checkpoint.parent.name or checkpoint.name
    return f"{label}, deterministic" if run.get("deterministic") else label


def _training_log(path: Path) -> Path | None:
    for candidate in (path / TRAINING_LOG, path.parent / TRAINING_LOG):
        if candidate.is_file():
            return candidate
    return None


def _settings(run: dict[str, Any]) -> dict[str, str]:
    """The run's task-changing options besides the split, dataset, found budget and goal set."""
    changed: dict[str, Any] = {}
    for section, values in (run.get("env_overrides") or {}).items():
        for name, value in values.items():
            changed[f"{section}.{name}"] = value
    changed.pop("task.found_budget", None)
    changed.pop("task.goal_set", None)
    sent = run.get("env_config") or {}
    max_steps = (sent.get("task") or {}).get("max_steps")
    if max_steps is not None:  # --max-steps
        changed["task.max_steps"] = max_steps
    # --image-size (recorded since `multion eval --set`; older runs only have the config sent,
    # which also holds the agent's own camera changes)
    width = run["image_size"] if "image_size" in run else (sent.get("camera") or {}).get("width")
    if width is not None:
        changed["camera.width"] = width
    return {key: str(value) for key, value in sorted(changed.items())}


def _joined(settings: dict[str, str]) -> str:
    return ", ".join(f"{key}={value}" for key, value in sorted(settings.items()))
