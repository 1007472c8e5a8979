"""The MultiON wire protocol, v1: routes, msgpack encoding, messages and space descriptions.

This one module is the contract between servers and clients (in the spirit of dm_env_rpc).

Transport
    HTTP/1.1; request and response bodies are msgpack (``application/x-msgpack``). Paths are
    versioned under ``/v1`` (see the ``*_PATH`` constants and :func:`session_path`).

Arrays
    numpy arrays travel as raw bytes, never as lists, in a msgpack extension type:
    ``ExtType(1, header + data)`` for an ``ndarray`` (0-d included) and ``ExtType(2, ...)`` for
    a numpy scalar (``np.int64(3)``), where ``header`` is ``u8 len(dtype) | dtype (ASCII numpy
    dtype string such as "<f4" or "|u1") | u8 ndim | ndim × u64 little-endian dims`` and
    ``data`` is the C-order buffer. Only bool, integer, float and complex dtypes are allowed.

Errors
    Every non-2xx response has the body ``{"error": {"code": str, "message": str}}``; the codes
    and their exception classes are in :mod:`multion_client.errors`.

Messages
    The dataclasses below; ``to_wire()`` gives the msgpack-able dict and ``from_wire()``
    validates a decoded dict, raising :class:`~multion_client.errors.MalformedMessage`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium import spaces

from multion_client.errors import MalformedMessage
from multion_client.schema import EXT_NDARRAY as EXT_NDARRAY
from multion_client.schema import EXT_SCALAR as EXT_SCALAR
from multion_client.schema import NDARRAY, OBSERVATION, message_schema, schema

# The encoding lives in .wire; it is part of this contract, so it is importable from here.
from multion_client.wire import decode as decode
from multion_client.wire import encode as encode
from multion_client.wire import encode_items as encode_items
from multion_client.wire import join_encoded as join_encoded
from multion_client.wire import space_from_wire as space_from_wire
from multion_client.wire import space_to_wire as space_to_wire

API_VERSION = "v1"
PREFIX = f"/{API_VERSION}"
CONTENT_TYPE = "application/x-msgpack"

HEALTH_PATH = f"{PREFIX}/health"
HEALTH_STATUSES = ("ok", "degraded")
SPEC_PATH = f"{PREFIX}/spec"
SESSIONS_PATH = f"{PREFIX}/sessions"

MAX_SEED = 2**63 - 1
"""Seeds are ints in [0, MAX_SEED] (numpy's generators take non-negative seeds)."""


def session_path(session_id: str, verb: str | None = None) -> str:
    """``/v1/sessions/{id}`` or ``/v1/sessions/{id}/{verb}`` (verb: reset, step, observe)."""
    base = f"{SESSIONS_PATH}/{session_id}"
    return base if verb is None else f"{base}/{verb}"


# ---------------------------------------------------------------------- messages
def _fields(data: Any, message: str, required: Sequence[str], optional: Sequence[str] = ()) -> dict:
    if not isinstance(data, Mapping):
        raise MalformedMessage(f"{message}: expected a map, got {type(data).__name__}")
    unknown = sorted(set(data) - set(required) - set(optional))
    if unknown:
        raise MalformedMessage(
            f"{message}: unknown field(s) {unknown}; fields are {list(required) + list(optional)}"
        )
    missing = [name for name in required if name not in data]
    if missing:
        raise MalformedMessage(f"{message}: missing field(s) {missing}")
    return dict(data)


def _list(value: Any, message: str, name: str) -> list[Any]:
    if not isinstance(value, (list, tuple)):
        raise MalformedMessage(f"{message}: '{name}' must be a list, got {type(value).__name__}")
    return list(value)


@dataclass(frozen=True)
class CreateSession:
    """``POST /v1/sessions``: ``config`` is an EnvConfig as nested dicts (plus ``episodes``)."""

    config: dict[str, Any] = field(
        default_factory=dict,
        metadata=schema(
            "an EnvConfig as nested maps (sections task, agent, camera, navgrid, maps; fields "
            "sensors, split, dataset, episodes_per_scene), plus `episodes`: a list of Episode "
            "maps to play. Missing fields keep their defaults (GET /v1/spec: `defaults`, and "
            "`ranges` for the allowed values); unknown fields are refused"
        ),
    )
    num_envs: int = field(default=1, metadata=schema("environments in the session", minimum=1))
    auto_reset: bool = field(
        default=False,
        metadata=schema(
            "reset an environment in the step that ends its episode (Gymnasium SAME_STEP)"
        ),
    )

    def to_wire(self) -> dict[str, Any]:
        return {"config": self.config, "num_envs": self.num_envs, "auto_reset": self.auto_reset}

    @classmethod
    def from_wire(cls, data: Any) -> CreateSession:
        d = _fields(data, "CreateSession", (), ("config", "num_envs", "auto_reset"))
        config, num_envs = d.get("config", {}), d.get("num_envs", 1)
        auto_reset = d.get("auto_reset", False)
        if not isinstance(config, Mapping):
            raise MalformedMessage("CreateSession: 'config' must be a map")
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise MalformedMessage(
                f"CreateSession: 'num_envs' must be an int ≥ 1, got {num_envs!r}"
            )
        if not isinstance(auto_reset, bool):
            raise MalformedMessage(
                f"CreateSession: 'auto_reset' must be a bool, got {auto_reset!r}"
            )
        return cls(dict(config), num_envs, auto_reset)


@dataclass(frozen=True)
class SessionInfo:
    """The answer to a create: the id and the spaces of each environment of the session."""

    session_id: str
    num_envs: int = field(metadata=schema(minimum=1))
    auto_reset: bool
    observation_space: spaces.Space[Any] = field(metadata=schema("of one environment"))
    action_space: spaces.Space[Any] = field(metadata=schema("of one environment"))

    def to_wire(self) -> dict[str, Any]:
        return {
            "session_id": self.session_id,
            "num_envs": self.num_envs,
            "auto_reset": self.auto_reset,
            "observation_space": space_to_wire(self.observation_space),
            "action_space": space_to_wire(self.action_space),
        }

    @classmethod
    def from_wire(cls, data: Any) -> SessionInfo:
        names = ("session_id", "num_envs", "auto_reset", "observation_space", "action_space")
        d = _fields(data, "SessionInfo", names)
        return cls(
            session_id=str(d["session_id"]),
            num_envs=int(d["num_envs"]),
            auto_reset=bool(d["auto_reset"]),
            observation_space=space_from_wire(d["observation_space"]),
            action_space=space_from_wire(d["action_space"]),
        )


@dataclass(frozen=True)
class Reset:
    """``POST /v1/sessions/{id}/reset``: one seed and one options map (or None) per env.

    Empty lists mean "None for every env". ``options`` are MultiONEnv's: ``episode_index``,
    ``episode_id`` or ``episode`` (an Episode dict).
    """

    seeds: list[int | None] = field(
        default_factory=list,
        metadata=schema(
            "one per environment: nil, or an int seed",
            items={
                "anyOf": [{"type": "integer", "minimum": 0, "maximum": MAX_SEED}, {"type": "null"}]
            },
        ),
    )
    options: list[dict[str, Any] | None] = field(
        default_factory=list,
        metadata=schema(
            "one per environment: nil, or a map with at most one of `episode_index` (int), "
            "`episode_id` (string), `episode` (an Episode map); other keys are refused",
            items={
                "anyOf": [
                    {
                        "type": "object",
                        "maxProperties": 1,
                        "additionalProperties": False,
                        "properties": {
                            "episode_index": {"type": "integer"},
                            "episode_id": {"type": "string"},
                            "episode": {"type": "object"},
                        },
                    },
                    {"type": "null"},
                ]
            },
        ),
    )

    def to_wire(self) -> dict[str, Any]:
        return {"seeds": self.seeds, "options": self.options}

    @classmethod
    def from_wire(cls, data: Any) -> Reset:
        d = _fields(data, "Reset", (), ("seeds", "options"))
        seeds = _list(d.get("seeds", []), "Reset", "seeds")
        options = _list(d.get("options", []), "Reset", "options")
        for index, seed in enumerate(seeds):
            if seed is not None and (
                isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED
            ):
                raise MalformedMessage(
                    f"Reset: seeds[{index}] = {seed!r:.40} is not allowed: seeds are nil or ints "
                    f"in [0, {MAX_SEED}]"
                )
        for option in options:
            if option is not None and not isinstance(option, Mapping):
                raise MalformedMessage(f"Reset: options must be maps or nil, got {option!r:.100}")
        return cls(seeds, options)


@dataclass(frozen=True)
class Step:
    """``POST /v1/sessions/{id}/step``: exactly one action per environment of the session."""

    actions: list[int] = field(
        metadata=schema(
            "one action per environment: 0 FOUND, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT "
            "(integers; a 1-d integer array is accepted too)",
            anyOf=[
                {"type": "array", "items": {"type": "integer", "minimum": 0, "maximum": 3}},
                NDARRAY,
            ],
        )
    )

    def to_wire(self) -> dict[str, Any]:
        return {"actions": self.actions}

    @classmethod
    def from_wire(cls, data: Any) -> Step:
        d = _fields(data, "Step", ("actions",))
        actions = d["actions"]
        if isinstance(actions, np.ndarray) and actions.ndim == 1:
            return cls(list(actions))  # a client's integer array (its dtype is checked per action)
        return cls(_list(actions, "Step", "actions"))


INFOS_TEXT = (
    "one per environment: `episode_id`, `scene_id` and `metrics` (the server's measures: "
    "success, progress, spl, ppl, …)"
)


@dataclass(frozen=True)
class Observations:
    """The answer to reset and observe: per env, the observation dict and the info dict."""

    observations: list[dict[str, Any]] = field(
        metadata=schema("one per environment", items=OBSERVATION)
    )
    infos: list[dict[str, Any]] = field(metadata=schema(INFOS_TEXT))

    def to_wire(self) -> dict[str, Any]:
        return {"observations": self.observations, "infos": self.infos}

    @classmethod
    def from_wire(cls, data: Any) -> Observations:
        d = _fields(data, "Observations", ("observations", "infos"))
        observations = _list(d["observations"], "Observations", "observations")
        return cls(observations, _list(d["infos"], "Observations", "infos"))


@dataclass(frozen=True)
class StepResult:
    """The answer to a step, per env. With auto-reset, see ``RemoteVectorEnv`` for the infos."""

    observations: list[dict[str, Any]] = field(
        metadata=schema("one per environment", items=OBSERVATION)
    )
    rewards: list[float]
    terminated: list[bool]
    truncated: list[bool]
    infos: list[dict[str, Any]] = field(
        metadata=schema(
            INFOS_TEXT + "; with auto_reset, an ended episode's last outputs are in "
            "`final_obs` and `final_info`"
        )
    )

    FIELDS = ("observations", "rewards", "terminated", "truncated", "infos")

    def to_wire(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in self.FIELDS}

    @classmethod
    def from_wire(cls, data: Any) -> StepResult:
        d = _fields(data, "StepResult", cls.FIELDS)
        lists = [_list(d[name], "StepResult", name) for name in cls.FIELDS]
        if len({len(v) for v in lists}) != 1:
            raise MalformedMessage("StepResult: the lists have different lengths")
        return cls(*lists)


@dataclass(frozen=True)
class Error:
    """The body of every error response."""

    code: str
    message: str

    def to_wire(self) -> dict[str, Any]:
        return {"error": {"code": self.code, "message": self.message}}

    @classmethod
    def from_wire(cls, data: Any) -> Error:
        inner = _fields(data, "Error", ("error",))["error"]
        d = _fields(inner, "Error", ("code", "message"))
        return cls(str(d["code"]), str(d["message"]))


@dataclass(frozen=True)
class SessionClosed:
    """The answer to ``DELETE /v1/sessions/{id}``."""

    closed: str = field(metadata=schema("the id of the closed session"))

    def to_wire(self) -> dict[str, Any]:
        return {"closed": self.closed}


@dataclass(frozen=True)
class Health:
    """The answer to ``GET /v1/health``: liveness, the simulator workers, sessions in use."""

    status: str = field(
        metadata=schema("`degraded` while a worker is being replaced", enum=list(HEALTH_STATUSES))
    )
    api_version: str
    workers: list[dict[str, Any]] = field(
        metadata=schema(
            "per worker: slot, pid, alive, ready, envs (held), reserved_mib (their memory "
            "estimates), limit_mib (its address-space limit)"
        )
    )
    workers_replaced: int
    sessions: int
    envs: int
    sessions_reaped: int

    def to_wire(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class ServerSpec:
    """The answer to ``GET /v1/spec``: the task, the config a session may ask for, the limits."""

    api_version: str
    actions: dict[str, int] = field(metadata=schema("action name → id"))
    goal_categories: list[str] = field(metadata=schema("category names; a category id is an index"))
    sensors: list[str]
    defaults: dict[str, Any] = field(metadata=schema("the default EnvConfig, as nested maps"))
    ranges: dict[str, str] = field(
        metadata=schema("config field (e.g. `camera.width`) → its allowed values")
    )
    observation_space: spaces.Space[Any] = field(metadata=schema("of the default config"))
    action_space: spaces.Space[Any]
    metadata: dict[str, Any] = field(metadata=schema("the environment's Gymnasium metadata"))
    autoreset_mode: str = field(metadata=schema(enum=["same_step"]))
    renderer: dict[str, Any] = field(
        metadata=schema(
            "`camera.renderer`: its `choices`, the `default`, and what `auto` renders with on "
            "this server (`egl` or `tiny`)"
        )
    )
    limits: dict[str, Any] = field(metadata=schema("this server's limits (sessions, envs, bytes)"))

    def to_wire(self) -> dict[str, Any]:
        wire = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        wire["observation_space"] = space_to_wire(self.observation_space)
        wire["action_space"] = space_to_wire(self.action_space)
        return wire


# ---------------------------------------------------------------------- leaderboard runs
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
            "per track: name, num_goals, kind, sensors (allowed), camera, metric (ranking), "
            "max_steps, phases (name, episodes, feedback, daily_quota, total_quota, sealed_until)"
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
        action = d["action"]
        if isinstance(action, float) and action.is_integer():
            action = int(action)
        if isinstance(action, bool) or not isinstance(action, int):
            from multion_client.errors import InvalidAction

            raise InvalidAction(f"RunStep: illegal action {action!r}; actions are 0..3")
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
    episodes_done: int
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
        values = {name: d.get(name) for name in (*cls.FIELDS, *cls.OPTIONAL)}
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
