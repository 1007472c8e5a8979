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
from multion_client.schema import NDARRAY, OBSERVATION, schema

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
RENDERER_HEADER = "multion-renderer"
"""The create answer's header naming what the session renders with (`camera.renderer`, `auto`
resolved by the worker). A header, not a field of SessionInfo, so that clients which refuse
unknown fields (every client before it) keep working with newer servers."""

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
def _fields(
    data: Any, message: str, required: Sequence[str], optional: Sequence[str] = ()
) -> dict[str, Any]:
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
            "sensors, split, dataset, episodes_per_scene, online_max_geodesic), plus `episodes`: a "
            "list of Episode maps to play. Missing fields keep their defaults (GET /v1/spec: "
            "`defaults`, and `ranges` for the allowed values); unknown fields are refused"
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
    renderer: str | None = field(default=None, metadata={"wire": False})
    """What the environments render with (``gl`` or ``tiny``), from the create answer's
    :data:`RENDERER_HEADER`; None from servers that do not send it."""

    def to_wire(self) -> dict[str, Any]:
        wire = {
            "session_id": self.session_id,
            "num_envs": self.num_envs,
            "auto_reset": self.auto_reset,
            "observation_space": space_to_wire(self.observation_space),
            "action_space": space_to_wire(self.action_space),
        }
        return wire  # the renderer travels in RENDERER_HEADER

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
            "`camera.renderer`: its `choices`, the `default`, what `auto` renders with on "
            "this server's simulator workers (`gl` or `tiny`; nil while none runs) and, where "
            "it falls back to `tiny`, why not `gl` (`gl_unavailable`)"
        )
    )
    limits: dict[str, Any] = field(metadata=schema("this server's limits (sessions, envs, bytes)"))
    goal_sets: dict[str, list[str]] = field(
        default_factory=dict,
        metadata=schema(
            "`task.goal_set` → its category names (a category id is an index); "
            "`goal_categories` are the default set's"
        ),
    )
    sources: dict[str, str] = field(
        default_factory=dict,
        metadata=schema(
            "config field (e.g. `maps.ego_size`) → where its default comes from: the paper, or "
            "the reference code (saimwani/multiON) with file and line"
        ),
    )

    def to_wire(self) -> dict[str, Any]:
        wire = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        wire["observation_space"] = space_to_wire(self.observation_space)
        wire["action_space"] = space_to_wire(self.action_space)
        return wire
