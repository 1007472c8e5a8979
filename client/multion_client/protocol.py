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

import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import msgpack
import numpy as np
from gymnasium import spaces

from multion_client.errors import MalformedMessage

API_VERSION = "v1"
PREFIX = f"/{API_VERSION}"
CONTENT_TYPE = "application/x-msgpack"

HEALTH_PATH = f"{PREFIX}/health"
SPEC_PATH = f"{PREFIX}/spec"
SESSIONS_PATH = f"{PREFIX}/sessions"

MAX_SEED = 2**63 - 1
"""Seeds are ints in [0, MAX_SEED] (numpy's generators take non-negative seeds)."""


def session_path(session_id: str, verb: str | None = None) -> str:
    """``/v1/sessions/{id}`` or ``/v1/sessions/{id}/{verb}`` (verb: reset, step, observe)."""
    base = f"{SESSIONS_PATH}/{session_id}"
    return base if verb is None else f"{base}/{verb}"


# ---------------------------------------------------------------------- encoding
EXT_NDARRAY = 1
EXT_SCALAR = 2
_ALLOWED_KINDS = "biufc"


def _array_ext(array: np.ndarray, code: int) -> msgpack.ExtType:
    if array.dtype.kind not in _ALLOWED_KINDS:
        raise TypeError(f"cannot encode numpy dtype {array.dtype} (only bool/int/float/complex)")
    if not array.flags.c_contiguous:
        array = array.copy(order="C")  # (not ascontiguousarray: it turns 0-d arrays into 1-d)
    dtype = array.dtype.str.encode("ascii")
    header = struct.pack(
        f"<B{len(dtype)}sB{array.ndim}Q", len(dtype), dtype, array.ndim, *array.shape
    )
    # One copy: the header and the raw buffer side by side, as the extension's payload.
    return msgpack.ExtType(code, b"".join((header, array.data)))


def _default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return _array_ext(obj, EXT_NDARRAY)
    if isinstance(obj, np.generic):
        return _array_ext(np.asarray(obj), EXT_SCALAR)
    if isinstance(obj, tuple):
        return list(obj)
    raise TypeError(f"cannot encode {type(obj).__name__} in a MultiON message")


def _ext_hook(code: int, data: bytes) -> Any:
    if code not in (EXT_NDARRAY, EXT_SCALAR):
        return msgpack.ExtType(code, data)
    try:
        (dtype_len,) = struct.unpack_from("<B", data, 0)
        dtype = np.dtype(data[1 : 1 + dtype_len].decode("ascii"))
        (ndim,) = struct.unpack_from("<B", data, 1 + dtype_len)
        shape = struct.unpack_from(f"<{ndim}Q", data, 2 + dtype_len)
    except (struct.error, UnicodeDecodeError, TypeError, ValueError) as error:
        raise MalformedMessage(f"bad array header in msgpack extension: {error}") from None
    offset = 2 + dtype_len + 8 * ndim
    count = int(np.prod(shape, dtype=np.int64))
    if dtype.kind not in _ALLOWED_KINDS or len(data) - offset != count * dtype.itemsize:
        raise MalformedMessage(f"bad array in msgpack extension: dtype {dtype}, shape {shape}")
    # Copy out of the message buffer so callers get ordinary writable arrays.
    array = np.frombuffer(data, dtype, count, offset).reshape(shape).copy()
    return array[()] if code == EXT_SCALAR else array


_packer_options = {"default": _default, "use_bin_type": True}


def encode(obj: Any) -> bytes:
    """msgpack bytes of ``obj`` (dicts, lists, str, numbers, bytes, numpy arrays and scalars)."""
    return msgpack.packb(obj, **_packer_options)


def decode(data: bytes | bytearray | memoryview) -> Any:
    """The object encoded in ``data``; raises :class:`MalformedMessage` for anything invalid."""
    try:
        return msgpack.unpackb(data, ext_hook=_ext_hook, raw=False)
    except MalformedMessage:
        raise
    except (ValueError, TypeError, msgpack.UnpackException) as error:
        raise MalformedMessage(
            f"body is not valid msgpack ({type(error).__name__}: {error})"
        ) from None


def encode_items(items: Sequence[Any]) -> bytes:
    """The msgpack encodings of ``items`` back to back, without an array header.

    With :func:`join_encoded` a server builds one response from parts encoded elsewhere
    (e.g. in several worker processes) without decoding and re-encoding arrays.
    """
    packer = msgpack.Packer(**_packer_options)
    return b"".join(packer.pack(item) for item in items)


def join_encoded(fields: Sequence[tuple[str, int, Sequence[bytes]]]) -> bytes:
    """Encode a map ``{name: [items...]}`` from ``(name, item count, encode_items parts)``."""
    packer = msgpack.Packer(**_packer_options)
    out = [packer.pack_map_header(len(fields))]
    for name, count, parts in fields:
        out.append(packer.pack(name))
        out.append(packer.pack_array_header(count))
        out.extend(parts)
    return b"".join(out)


# ---------------------------------------------------------------------- spaces
def space_to_wire(space: spaces.Space[Any]) -> dict[str, Any]:
    """A msgpack-able description of a Box, Discrete or Dict space."""
    if isinstance(space, spaces.Box):
        return {
            "type": "Box",
            "low": _compact(space.low),
            "high": _compact(space.high),
            "shape": list(space.shape),
            "dtype": np.dtype(space.dtype).str,
        }
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    if isinstance(space, spaces.Dict):
        return {
            "type": "Dict",
            "spaces": {name: space_to_wire(sub) for name, sub in space.spaces.items()},
        }
    raise TypeError(f"cannot describe a {type(space).__name__} space on the wire")


def _compact(bound: np.ndarray) -> np.ndarray | np.generic:
    """A uniform bound as one scalar (an image's Box would otherwise cost its size twice)."""
    flat = bound.reshape(-1)
    if flat.size and (flat == flat[0]).all():
        return flat[0]
    return bound


def space_from_wire(data: Any) -> spaces.Space[Any]:
    """Rebuild a space from :func:`space_to_wire`'s description."""
    kind = data.get("type") if isinstance(data, Mapping) else None
    try:
        if kind == "Box":
            return spaces.Box(
                low=data["low"],
                high=data["high"],
                shape=tuple(data["shape"]),
                dtype=np.dtype(data["dtype"]),
            )
        if kind == "Discrete":
            return spaces.Discrete(int(data["n"]), start=int(data.get("start", 0)))
        if kind == "Dict":
            return spaces.Dict({k: space_from_wire(v) for k, v in data["spaces"].items()})
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise MalformedMessage(f"bad {kind} space description: {error}") from None
    raise MalformedMessage(f"unsupported space description {data!r:.200}")


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

    config: dict[str, Any] = field(default_factory=dict)
    num_envs: int = 1
    auto_reset: bool = False

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
    num_envs: int
    auto_reset: bool
    observation_space: spaces.Space[Any]
    action_space: spaces.Space[Any]

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

    seeds: list[int | None] = field(default_factory=list)
    options: list[dict[str, Any] | None] = field(default_factory=list)

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

    actions: list[int]

    def to_wire(self) -> dict[str, Any]:
        return {"actions": self.actions}

    @classmethod
    def from_wire(cls, data: Any) -> Step:
        d = _fields(data, "Step", ("actions",))
        actions = d["actions"]
        if isinstance(actions, np.ndarray) and actions.ndim == 1:
            return cls(list(actions))  # a client's integer array (its dtype is checked per action)
        return cls(_list(actions, "Step", "actions"))


@dataclass(frozen=True)
class Observations:
    """The answer to reset and observe: per env, the observation dict and the info dict."""

    observations: list[dict[str, Any]]
    infos: list[dict[str, Any]]

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

    observations: list[dict[str, Any]]
    rewards: list[float]
    terminated: list[bool]
    truncated: list[bool]
    infos: list[dict[str, Any]]

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
