"""Evaluating an agent on a split: episodes in, per-episode metrics (from the server) out.

The agent runs here, in the client process, and sees only the sensors it asked for; the server
steps the simulator and is the only authority on metrics (``info["metrics"]`` of the last step).
The evaluator additionally asks for ``gps`` so it can draw the path afterwards, and hides it
from agents that did not ask for it.

Which episodes: the packaged dataset of the task and split (or ``dataset``), read locally to know
its ids and start poses; ``episodes=N`` takes N evenly spaced ones, so every scene is visited.
Each episode is reset by id on the server, and the agent's random stream is re-seeded from
``(seed, episode id)`` (:mod:`multion_agents.seeding`): results do not depend on the number of
workers or their order, and an episode draws the same in every run that holds it.
"""

from __future__ import annotations

import copy
import functools
import queue
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

from multion.config.codec import env_config_from_dict, env_config_to_dict, session_config_from_dict
from multion.config.datasets import (
    dataset_sha256,
    load_dataset,
    packaged_dataset_path,
    read_header,
    task_name,
)
from multion.config.episode import Episode
from multion.config.errors import UsageError
from multion.config.ranges import ConfigError
from multion.config.task import EnvConfig
from multion.scenes.viz import gps_to_world
from multion_agents.agent import Agent, AgentError, ConfigOverrides, merge_overrides
from multion_agents.eval_settings import DEFAULT_SPLIT, EvalSettings
from multion_agents.registry import SETUP_TORCH, agent_class, torch_installed
from multion_agents.seeding import SEED_SCHEME, scheme_seed
from multion_agents.seeding import episode_seed as episode_seed
from multion_client.client import Client
from multion_client.env import RemoteEnv

EnvFactory = Callable[[dict[str, Any]], gym.Env]
"""Builds one environment from a config dict (EnvConfig as nested dicts)."""

RECORDED_SENSOR = "gps"


class EpisodeMismatchError(UsageError, RuntimeError):
    """The server played another episode than the one asked for: client and server datasets
    differ."""


@dataclass
class EpisodeRecord:
    """One played episode: the server's metrics, the path walked, and the time spent."""

    index: int
    episode_id: str
    scene_id: str
    metrics: dict[str, Any]
    path: np.ndarray  # (T + 1, 2) world x, y from the start to the end
    agent_seconds: float
    total_seconds: float
    actions: list[int] = field(default_factory=list)
    """The actions played, in order: what ``multion video`` replays to film the episode."""

    def to_json(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "episode_id": self.episode_id,
            "scene_id": self.scene_id,
            "metrics": self.metrics,
            "agent_seconds": round(self.agent_seconds, 4),
            "total_seconds": round(self.total_seconds, 4),
            "actions": actions_text(self.actions),
        }


def actions_text(actions: Sequence[int]) -> str:
    """Actions as one digit each (0 FOUND, 1 forward, 2 left, 3 right), as the leaderboard
    stores them: a 2,500-step episode is a 2,500-character string in ``episodes.jsonl``."""
    return "".join(str(int(action)) for action in actions)


@dataclass
class EvalResult:
    settings: EvalSettings
    config: dict[str, Any]
    records: list[EpisodeRecord]
    episodes: list[Episode]
    server: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    resolved_config: dict[str, Any] = field(default_factory=dict)
    """Every field of the environment config, defaults included (what the report compares)."""
    dataset_sha256: str = ""
    """Fingerprint of the dataset file the episodes came from."""
    agent_settings: dict[str, Any] = field(default_factory=dict)
    """The agent's own tunables (``Agent.recorded_settings``); empty for agents without any."""
    seed_scheme: str = SEED_SCHEME
    """How each episode's agent was seeded (:mod:`multion_agents.seeding`)."""


# ---------------------------------------------------------------------- episodes and config
def select_episodes(settings: EvalSettings) -> list[Episode]:
    """The evaluated episodes, in order; evenly spaced when fewer than the dataset's."""
    every = load_dataset(dataset_file(settings), settings.num_goals)
    count = len(every) if settings.episodes is None else min(settings.episodes, len(every))
    if count <= 0:
        raise ConfigError(f"--episodes must be positive, got {settings.episodes}")
    return [every[i * len(every) // count] for i in range(count)]


def dataset_file(settings: EvalSettings) -> Path:
    """The dataset file the evaluated episodes are read from."""
    split = settings.split or DEFAULT_SPLIT
    return Path(settings.dataset or packaged_dataset_path(settings.num_goals, split))


def with_played_split(settings: EvalSettings) -> EvalSettings:
    """``settings`` with the split its episodes come from, as the run records it: ``--split``
    (``DEFAULT_SPLIT`` if none), or the split a ``--dataset`` file names, which a ``--split``
    given must match."""
    named = read_header(settings.dataset).get("split") if settings.dataset is not None else None
    if named is not None and settings.split is not None and settings.split != named:
        raise ConfigError(
            f"--split {settings.split}: {settings.dataset} holds {named} episodes (its header's "
            f'"split"); give --split {named}, or leave --split out'
        )
    return replace(settings, split=settings.split or named or DEFAULT_SPLIT)


def env_config(settings: EvalSettings, agent: type[Agent]) -> dict[str, Any]:
    """The environment config the agent is evaluated with, as the server's nested dicts.

    The agent's ``config_overrides`` are applied first, then the user's ``env_overrides``, so an
    explicit ``--set`` wins (and is recorded in ``metrics.json``)."""
    sensors = list(dict.fromkeys([*agent.sensors, RECORDED_SENSOR]))
    config: dict[str, Any] = {
        "task": {"num_goals": settings.num_goals},
        "sensors": sensors,
        "split": settings.split,
    }
    if settings.max_steps is not None:
        config["task"]["max_steps"] = settings.max_steps
    if settings.dataset is not None:
        config["dataset"] = str(settings.dataset)
        distractors = int(read_header(settings.dataset).get("num_distractors", 0))
        if distractors:  # the env checks that its task matches the dataset
            config["task"]["num_distractors"] = distractors
    if settings.image_size is not None:
        config["camera"] = {"width": settings.image_size, "height": settings.image_size}
    config = merge_overrides(config, agent.config_overrides)
    return merge_overrides(config, settings.env_overrides)


def check_overrides(overrides: ConfigOverrides) -> None:
    """Refuse ``--set`` fields that other options own (the task's m is ``--task``)."""
    if "num_goals" in overrides.get("task", {}):
        raise ConfigError("--set task.num_goals: give the number of goals with --task instead")
    for section, values in overrides.items():
        if not isinstance(values, dict):
            raise ConfigError(f"--set {section}: expected SECTION.FIELD=VALUE")


def resolve_config(config: dict[str, Any]) -> dict[str, Any]:
    """Every field of ``config`` with defaults filled in; a ConfigError names a bad field."""
    return env_config_to_dict(env_config_from_dict(config))


def session_config(
    config: dict[str, Any], server_defaults: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The resolved config of a session created with ``config`` on a server whose defaults are
    ``server_defaults`` (``GET /v1/spec``): the server's default for every field the request
    leaves out (this package's default for a field the server does not report), so an agent
    learns the camera and steps it will really get from a server of another version."""
    base: dict[str, Any] = {}
    for section, fields in resolve_config({}).items():
        theirs = (server_defaults or {}).get(section)
        if isinstance(fields, dict) and isinstance(theirs, dict):
            base[section] = {key: theirs[key] for key in fields if key in theirs}
    merged = {**base}
    for key, value in config.items():
        merged[key] = {**base.get(key, {}), **value} if isinstance(value, dict) else value
    return resolve_config(merged)


def configured_agent(cls: type[Agent], seed: int, resolved: dict[str, Any]) -> Agent:
    """An agent of class ``cls`` that has been given its environment's resolved config
    (:meth:`Agent.configure`); an AgentError when it cannot work with it."""
    agent = cls(seed=seed)
    agent.configure(copy.deepcopy(resolved))
    return agent


def resolve_agent(settings: EvalSettings) -> type[Agent]:
    """The agent class: a registered or import-path agent, or a learned one from a checkpoint."""
    if settings.checkpoint is None:
        if settings.found_gate is not None:
            raise AgentError("--found-gate is for learned agents (--checkpoint)")
        return agent_class(settings.agent)
    if not torch_installed():
        raise AgentError(f"--checkpoint {settings.checkpoint}: {SETUP_TORCH}")
    return _learned_class(
        settings.agent, settings.checkpoint, settings.deterministic, settings.found_gate
    )


@functools.cache
def _learned_class(
    agent: str, checkpoint: str, deterministic: bool, found_gate: float | None
) -> type[Agent]:
    # cached: the evaluator resolves the agent more than once, and a checkpoint is read once
    from multion_agents.learned.agent import learned_agent_class
    from multion_agents.learned.models import MODELS

    if agent not in MODELS:
        raise AgentError(f"--checkpoint is for learned agents ({', '.join(MODELS)}), not {agent!r}")
    cls = learned_agent_class(checkpoint, deterministic, found_gate)
    if cls.model != agent:
        raise AgentError(f"{checkpoint} holds a {cls.model!r} agent, not {agent!r}")
    return cls


# ---------------------------------------------------------------------- playing
def run_episode(
    env: gym.Env,
    agent: Agent,
    episode: Episode,
    index: int = 0,
    options: dict[str, Any] | None = None,
) -> EpisodeRecord:
    """Play one episode to its end; the env must give ``gps`` (for the recorded path)."""
    started = time.perf_counter()
    observation, info = env.reset(options=options or {"episode_id": episode.episode_id})
    if info.get("episode_id") != episode.episode_id:
        raise EpisodeMismatchError(
            f"the server played episode {info.get('episode_id')!r} instead of "
            f"{episode.episode_id!r}: do client and server have the same dataset?"
        )
    agent.reset()
    visible = set(agent.sensors)
    gps = [np.asarray(observation[RECORDED_SENSOR], dtype=np.float64)]
    actions: list[int] = []
    thinking = 0.0
    done = False
    while not done:
        tick = time.perf_counter()
        action = agent.act({k: v for k, v in observation.items() if k in visible})
        thinking += time.perf_counter() - tick
        observation, _, terminated, truncated, info = env.step(action)
        actions.append(int(action))
        gps.append(np.asarray(observation[RECORDED_SENSOR], dtype=np.float64))
        done = terminated or truncated
    return EpisodeRecord(
        index=index,
        episode_id=episode.episode_id,
        scene_id=episode.scene_id,
        metrics=dict(info["metrics"]),
        path=gps_to_world(np.asarray(gps), episode),
        agent_seconds=thinking,
        total_seconds=time.perf_counter() - started,
        actions=actions,
    )


def scene_order(episodes: Sequence[Episode]) -> list[int]:
    """Episode indices grouped by scene (scenes in order of first appearance, episodes in
    order within a scene): each environment then builds each house once. Results do not
    depend on the order (agents are seeded per episode id)."""
    first: dict[str, int] = {}
    for index, episode in enumerate(episodes):
        first.setdefault(episode.scene_id, index)
    return sorted(range(len(episodes)), key=lambda i: (first[episodes[i].scene_id], i))


def play_all(
    settings: EvalSettings,
    episodes: Sequence[Episode],
    make_env: EnvFactory,
    progress: bool = True,
    server_defaults: dict[str, Any] | None = None,
) -> tuple[dict[str, Any], list[EpisodeRecord]]:
    """Play ``episodes`` with ``settings.workers`` threads, one env and one agent each; each
    agent is given the resolved config of its environments (with ``server_defaults``, the
    server's ``GET /v1/spec`` defaults, for fields the config leaves out)."""
    cls = resolve_agent(settings)
    config = env_config(settings, cls)
    resolved = session_config(config, server_defaults)
    # one (env, agent) pair per worker thread, created on first need and handed back after use
    idle: queue.SimpleQueue[tuple[gym.Env, Agent]] = queue.SimpleQueue()
    opened: list[gym.Env] = []
    lock = threading.Lock()

    def play(index: int) -> EpisodeRecord:
        try:
            env, agent = idle.get_nowait()
        except queue.Empty:
            agent = configured_agent(cls, settings.seed, resolved)
            env = make_env(config)
            with lock:
                opened.append(env)
        try:
            episode = episodes[index]
            agent.seed(scheme_seed(SEED_SCHEME, settings.seed, index, episode.episode_id))
            return run_episode(env, agent, episode, index)
        finally:
            idle.put((env, agent))

    records: list[EpisodeRecord] = []
    bar = tqdm(
        total=len(episodes),
        desc=f"{settings.agent} {task_name(settings.num_goals)} {settings.split}",
        unit="ep",
        disable=not progress,
    )
    try:
        with ThreadPoolExecutor(max_workers=max(1, settings.workers)) as pool:
            for record in pool.map(play, scene_order(episodes)):
                records.append(record)
                done = [r.metrics.get("success", 0.0) for r in records]
                bar.set_postfix(success=f"{100 * float(np.mean(done)):.0f}%")
                bar.update(1)
    finally:
        bar.close()
        for env in opened:
            env.close()
    return config, sorted(records, key=lambda r: r.index)


def remote_env_factory(url: str) -> EnvFactory:
    """Environments served by the MultiON server at ``url``."""

    def make(config: dict[str, Any]) -> gym.Env:
        return RemoteEnv(url, config)

    return make


def local_env_factory() -> EnvFactory:
    """In-process environments (no server), e.g. for tests and debugging agents."""
    from multion.task.env import MultiONEnv

    def make(config: dict[str, Any]) -> gym.Env:
        env_config_, inline = session_config_from_dict(config)
        return MultiONEnv(env_config_, episodes=inline)

    return make


def evaluate(settings: EvalSettings, progress: bool = True) -> EvalResult:
    """Evaluate against ``settings.server``, or a local server started (and stopped) here, or
    in this process with ``settings.in_process``."""
    # fail on a bad agent, checkpoint or config before starting anything
    check_overrides(settings.env_overrides)
    settings = with_played_split(settings)
    cls = resolve_agent(settings)
    resolved = resolve_config(env_config(settings, cls))
    # an agent refuses a config it cannot use; its tunables are recorded with the run
    agent_settings = configured_agent(cls, settings.seed, resolved).recorded_settings()
    episodes = select_episodes(settings)
    started = time.perf_counter()
    if settings.in_process:
        from multion.sim.camera import resolve_renderer

        config, records = play_all(settings, episodes, local_env_factory(), progress)
        server: dict[str, Any] = {"url": None, "local": False, "in_process": True}
        server["renderer"] = resolve_renderer(_requested_renderer(config))
    elif settings.server is not None:
        with Client(settings.server, retries=1) as client:
            health, spec = client.health(), client.spec()
        config, records = play_all(
            settings, episodes, remote_env_factory(settings.server), progress, spec.get("defaults")
        )
        server = {"url": settings.server, "local": False, "api_version": health.get("api_version")}
        server["renderer"] = _served_renderer(config, spec)
    else:
        from multion.api.local_server import LocalServer

        # The local server may read the --dataset file's directory (servers refuse other paths).
        allow = (
            ["--dataset-dir", str(Path(settings.dataset).resolve().parent)]
            if settings.dataset is not None
            else []
        )
        with LocalServer(workers=max(1, settings.workers), options=allow) as local:
            with Client(local.url) as client:
                health, spec = client.health(), client.spec()
            config, records = play_all(
                settings, episodes, remote_env_factory(local.url), progress, spec.get("defaults")
            )
        server = {"url": None, "local": True, "api_version": health.get("api_version")}
        server["renderer"] = _served_renderer(config, spec)
    # Which dataset was played, and for which houses (kept with the server's details, which
    # metrics.json records as run.server).
    played = dataset_file(settings)
    header = read_header(played)
    server["dataset"] = {
        "path": str(played) if settings.dataset else f"packaged:{played.parent.name}/{played.name}",
        "version": header.get("version"),
        "scene_generator_version": header.get("scene_generator_version"),
        "num_distractors": header.get("num_distractors", 0),
    }
    return EvalResult(
        settings,
        config,
        records,
        episodes,
        server,
        seconds=time.perf_counter() - started,
        resolved_config=resolved,
        dataset_sha256=dataset_sha256(dataset_file(settings)),
        agent_settings=agent_settings,
    )


def _requested_renderer(config: dict[str, Any]) -> str:
    return str(config.get("camera", {}).get("renderer", EnvConfig().camera.renderer))


def _served_renderer(config: dict[str, Any], spec: dict[str, Any]) -> str | None:
    """The renderer the server's environments used ("auto" resolved by the server's spec)."""
    requested = _requested_renderer(config)
    if requested != "auto":
        return requested
    served: str | None = spec.get("renderer", {}).get("auto")  # None: a server older than the field
    return served
