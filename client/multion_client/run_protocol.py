"""The leaderboard's run messages, beside the session messages of :mod:`multion_client.protocol`
(same transport, encoding and errors): a *run* plays the hidden episodes of one (track, phase)
of a challenge, which the server chooses; see ``docs/leaderboard.md``."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from gymnasium import spaces

from multion_client.constants import ACTIONS_TEXT, NUM_ACTIONS, action_id
from multion_client.errors import MalformedMessage
from multion_client.protocol import PREFIX, _fields, _list, space_from_wire, space_to_wire
from multion_client.schema import OBSERVATION, message_schema, schema

# A *run* plays the hidden episodes of one (track, phase) of a challenge, in an order the server
# chooses. Every run route needs ``Authorization: Bearer <team token>``; a team sees only its
# own runs. The server sends only what the track allows: no episode or scene ids, no goal
# positions, no seeds, no rewards and no per-step metrics.
CHALLENGE_PATH = f"{PREFIX}/challenge"
RUNS_PATH = f"{PREFIX}/runs"
RUN_FORBIDDEN_FIELDS = ("seed", "seeds", "options", "episode_id", "episode_index", "config")
"""Fields of a session's reset that a run refuses with ``not_allowed_in_run`` (403)."""


def run_path(run_id: str, verb: str | None = None) -> str:
    """``/v1/runs/{id}`` or ``/v1/runs/{id}/{verb}`` (verb: episodes, step, observe)."""
    base = f"{RUNS_PATH}/{run_id}"
    return base if verb is None else f"{base}/{verb}"


def _refuse_run_fields(data: Any, message: str) -> None:
    from multion_client.errors import NotAllowedInRun

    if isinstance(data, Mapping):
        bad = sorted(set(data) & set(RUN_FORBIDDEN_FIELDS))
        if bad:
            raise NotAllowedInRun(
                f"{message}: {bad} cannot be chosen in a run: the server picks the episodes, "
                "their order and their seeds"
            )


def _text(value: Any, message: str, name: str, limit: int, optional: bool = False) -> str | None:
    if value is None and optional:
        return None
    if not isinstance(value, str) or not value.strip() or len(value) > limit:
        raise MalformedMessage(f"{message}: '{name}' must be a non-empty string of ≤ {limit} chars")
    return value


def _url(value: Any, message: str, name: str) -> str | None:
    text = _text(value, message, name, 500, optional=True)
    if text is not None and not text.startswith(("https://", "http://")):
        raise MalformedMessage(f"{message}: '{name}' must be an http(s):// address")
    return text


def _count(value: Any, message: str, name: str, low: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise MalformedMessage(f"{message}: '{name}' must be an int ≥ {low}, got {value!r:.60}")
    return value


@dataclass(frozen=True)
class ChallengeInfo:
    """``GET /v1/challenge``: the tracks, their phases and the time limits of a run."""

    name: str
    limits: dict[str, Any] = field(
        metadata=schema("step_timeout_s, max_consecutive_timeouts, run_timeout_s")
    )
    tracks: list[dict[str, Any]] = field(
        metadata=schema(
            "per track: name, num_goals, kind, sensors (allowed), camera, maps (the oracle maps' "
            "MapConfig a run gets unless it chooses its own), metric (ranking), max_steps, "
            "num_distractors, success_distance, found_budget, goal_set, phases (name, episodes, "
            "feedback, daily_quota, total_quota, sealed_until)"
        )
    )

    def to_wire(self) -> dict[str, Any]:
        return {"name": self.name, "limits": self.limits, "tracks": self.tracks}

    @classmethod
    def from_wire(cls, data: Any) -> ChallengeInfo:
        d = _fields(data, "ChallengeInfo", ("name", "limits", "tracks"))
        return cls(str(d["name"]), dict(d["limits"]), _list(d["tracks"], "ChallengeInfo", "tracks"))


@dataclass(frozen=True)
class CreateRun:
    """``POST /v1/runs``: start a run of ``track`` / ``phase`` (debits the team's quota).

    ``sensors`` (default: every sensor the track allows) must be allowed by the track; ``maps``
    (MapConfig fields for the oracle maps) only on tracks that allow them. ``num_envs``
    episodes are played at once (lanes: lane k plays the run's episodes k, k + K …), up to the
    challenge's ``max_envs_per_run``.
    """

    track: str
    phase: str
    method: str
    sensors: list[str] | None = None
    maps: dict[str, Any] | None = None
    paper_url: str | None = None
    code_url: str | None = None
    num_envs: int = field(default=1, metadata=schema("episodes played at once", minimum=1))

    FIELDS = ("track", "phase", "method")
    OPTIONAL = ("sensors", "maps", "paper_url", "code_url", "num_envs")

    def to_wire(self) -> dict[str, Any]:
        wire = {name: getattr(self, name) for name in self.FIELDS}
        wire.update({k: getattr(self, k) for k in self.OPTIONAL if getattr(self, k) is not None})
        if self.num_envs == 1:
            del wire["num_envs"]  # the default: what servers before lanes understood
        return wire

    @classmethod
    def from_wire(cls, data: Any) -> CreateRun:
        _refuse_run_fields(data, "CreateRun")
        d = _fields(data, "CreateRun", cls.FIELDS, cls.OPTIONAL)
        sensors = d.get("sensors")
        if sensors is not None:
            sensors = _list(sensors, "CreateRun", "sensors")
            if not all(isinstance(s, str) for s in sensors) or not sensors:
                raise MalformedMessage("CreateRun: 'sensors' must be a non-empty list of names")
        maps = d.get("maps")
        if maps is not None and not isinstance(maps, Mapping):
            raise MalformedMessage("CreateRun: 'maps' must be a map of MapConfig fields")
        return cls(
            track=str(_text(d["track"], "CreateRun", "track", 40)),
            phase=str(_text(d["phase"], "CreateRun", "phase", 40)),
            method=str(_text(d["method"], "CreateRun", "method", 120)),
            sensors=sensors,
            maps=None if maps is None else dict(maps),
            paper_url=_url(d.get("paper_url"), "CreateRun", "paper_url"),
            code_url=_url(d.get("code_url"), "CreateRun", "code_url"),
            num_envs=_count(d.get("num_envs", 1), "CreateRun", "num_envs", 1),
        )


@dataclass(frozen=True)
class RunInfo:
    """The answer to creating a run: its id, size, the spaces and the time limits."""

    run_id: str
    track: str
    phase: str
    num_episodes: int
    sensors: list[str]
    observation_space: spaces.Space[Any]
    action_space: spaces.Space[Any]
    limits: dict[str, Any]
    num_envs: int = field(default=1, metadata=schema("lanes: episodes played at once", minimum=1))

    FIELDS = ("run_id", "track", "phase", "num_episodes", "sensors", "observation_space",
              "action_space", "limits")  # fmt: skip
    OPTIONAL = ("num_envs",)

    def to_wire(self) -> dict[str, Any]:
        wire = {name: getattr(self, name) for name in (*self.FIELDS, *self.OPTIONAL)}
        wire["observation_space"] = space_to_wire(self.observation_space)
        wire["action_space"] = space_to_wire(self.action_space)
        return wire

    @classmethod
    def from_wire(cls, data: Any) -> RunInfo:
        d = _fields(data, "RunInfo", cls.FIELDS, cls.OPTIONAL)
        return cls(
            run_id=str(d["run_id"]),
            track=str(d["track"]),
            phase=str(d["phase"]),
            num_episodes=_count(d["num_episodes"], "RunInfo", "num_episodes", 1),
            sensors=[str(s) for s in _list(d["sensors"], "RunInfo", "sensors")],
            observation_space=space_from_wire(d["observation_space"]),
            action_space=space_from_wire(d["action_space"]),
            limits=dict(d["limits"]) if isinstance(d["limits"], Mapping) else {},
            num_envs=_count(d.get("num_envs", 1), "RunInfo", "num_envs", 1),
        )


@dataclass(frozen=True)
class StartEpisode:
    """``POST /v1/runs/{id}/episodes``: start the run's episode number ``episode`` (0-based).

    It must be the next one, after the current one has ended. Sending the number of the episode
    already started returns its current observation again (a retry after a dropped connection).
    No seeds, options or episode choice: :data:`RUN_FORBIDDEN_FIELDS` are refused.
    """

    episode: int = field(metadata=schema("the next episode's run-order number", minimum=0))

    def to_wire(self) -> dict[str, Any]:
        return {"episode": self.episode}

    @classmethod
    def from_wire(cls, data: Any) -> StartEpisode:
        _refuse_run_fields(data, "StartEpisode")
        d = _fields(data, "StartEpisode", ("episode",))
        return cls(_count(d["episode"], "StartEpisode", "episode"))


@dataclass(frozen=True)
class RunStep:
    """``POST /v1/runs/{id}/step``: action number ``seq`` (1, 2, …) of episode ``episode``.

    Sending the last ``(episode, seq)`` again returns the stored answer without acting twice.
    """

    episode: int = field(metadata=schema("run-order number of the current episode", minimum=0))
    seq: int = field(metadata=schema("this action's number in the episode, from 1", minimum=1))
    action: int = field(
        metadata=schema("0 FOUND, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT", minimum=0, maximum=3)
    )

    def to_wire(self) -> dict[str, Any]:
        return {"episode": self.episode, "seq": self.seq, "action": self.action}

    @classmethod
    def from_wire(cls, data: Any) -> RunStep:
        _refuse_run_fields(data, "RunStep")
        d = _fields(data, "RunStep", ("episode", "seq", "action"))
        action = action_id(d["action"])  # the in-process env's rule: no floats, even 1.0
        if action is None:
            from multion_client.errors import InvalidAction

            raise InvalidAction(
                f"RunStep: illegal 'action' {d['action']!r:.60}; an action is an integer in "
                f"[0, {NUM_ACTIONS - 1}]: {ACTIONS_TEXT}"
            )
        return cls(
            _count(d["episode"], "RunStep", "episode"),
            _count(d["seq"], "RunStep", "seq", 1),
            action,
        )


@dataclass(frozen=True)
class RunObservation:
    """The answer to starting an episode, a step, or observe: where the run stands.

    ``episode`` is the run-order number of the current (or last) episode, -1 before the first;
    ``seq`` the number of actions taken in it.

    ``done`` ends the episode (``end_reason``: success, wrong_found, max_steps, timeout);
    ``metrics`` are sent only when the episode is done and the phase gives per-episode
    feedback; ``run_done`` says no episode is left.
    """

    episode: int = field(
        metadata=schema("run-order number of the episode; -1 before the first", minimum=-1)
    )
    seq: int = field(metadata=schema("actions taken in the episode", minimum=0))
    observation: dict[str, Any] = field(metadata=schema(**OBSERVATION))
    done: bool
    end_reason: str | None = None
    metrics: dict[str, Any] | None = field(
        default=None, metadata=schema("the episode's metrics, at its end, on phases that show them")
    )
    run_done: bool = False

    FIELDS = ("episode", "seq", "observation", "done")
    OPTIONAL = ("end_reason", "metrics", "run_done")

    def to_wire(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in (*self.FIELDS, *self.OPTIONAL)}

    @classmethod
    def from_wire(cls, data: Any) -> RunObservation:
        d = _fields(data, "RunObservation", cls.FIELDS, cls.OPTIONAL)
        observation = d["observation"]
        if not isinstance(observation, Mapping):
            raise MalformedMessage("RunObservation: 'observation' must be a map")
        return cls(
            episode=_count(d["episode"], "RunObservation", "episode", -1),
            seq=_count(d["seq"], "RunObservation", "seq"),
            observation=dict(observation),
            done=bool(d["done"]),
            end_reason=d.get("end_reason"),
            metrics=d.get("metrics"),
            run_done=bool(d.get("run_done", False)),
        )


@dataclass(frozen=True)
class RunStatus:
    """``GET /v1/runs/{id}``: a run's state, progress, why it ended, and what the phase shows.

    ``state``: running, finished, ended (stopped early: ``end_reason`` says why; missing
    episodes count as failures) or failed (the server broke it; refunded). ``results`` holds
    aggregates with 95% intervals and ``episodes`` per-episode metrics, when the phase shows them.
    """

    run_id: str
    track: str
    phase: str
    method: str
    state: str
    end_reason: str | None
    num_episodes: int
    episodes_done: int = field(
        metadata=schema(
            "episodes played to their end (the pages' completed ones): not those never played "
            "or cut short when the run ended (abandoned, or refunded)"
        )
    )
    episode: int
    episode_active: bool
    seq: int
    created_at: str
    finished_at: str | None
    refunded: bool
    baseline: bool
    results: dict[str, Any] | None = None
    episodes: list[dict[str, Any]] | None = None
    num_envs: int = 1
    lanes: list[dict[str, Any]] | None = field(
        default=None,
        metadata=schema("per lane: episode (current or last), episode_active, seq"),
    )

    FIELDS = ("run_id", "track", "phase", "method", "state", "end_reason", "num_episodes",
              "episodes_done", "episode", "episode_active", "seq", "created_at", "finished_at",
              "refunded", "baseline")  # fmt: skip
    OPTIONAL = ("results", "episodes", "num_envs", "lanes")

    def to_wire(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in (*self.FIELDS, *self.OPTIONAL)}

    @classmethod
    def from_wire(cls, data: Any) -> RunStatus:
        d = _fields(data, "RunStatus", cls.FIELDS, cls.OPTIONAL)
        values: dict[str, Any] = {name: d.get(name) for name in (*cls.FIELDS, *cls.OPTIONAL)}
        values["num_envs"] = d.get("num_envs", 1)
        return cls(**values)


@dataclass(frozen=True)
class RunList:
    """``GET /v1/runs``: the calling team's runs, newest first."""

    runs: list[RunStatus] = field(
        metadata=schema(anyOf=[{"type": "array", "items": message_schema(RunStatus)}])
    )

    def to_wire(self) -> dict[str, Any]:
        return {"runs": [r.to_wire() for r in self.runs]}

    @classmethod
    def from_wire(cls, data: Any) -> RunList:
        d = _fields(data, "RunList", ("runs",))
        return cls([RunStatus.from_wire(r) for r in _list(d["runs"], "RunList", "runs")])
