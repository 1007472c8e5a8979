"""msgpack encoding of MultiON messages: numpy arrays as raw bytes, Gymnasium spaces as maps.

See :mod:`multion_client.protocol` for the layout of the array extensions.
"""

from __future__ import annotations

import contextlib
import math
import struct
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any

import msgpack
import numpy as np
from gymnasium import spaces

from multion_client.errors import MalformedMessage
from multion_client.schema import EXT_NDARRAY, EXT_SCALAR

# ---------------------------------------------------------------------- encoding
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
    count = math.prod(shape)  # (Python ints: np.prod costs ~10 µs an array)
    if dtype.kind not in _ALLOWED_KINDS or len(data) - offset != count * dtype.itemsize:
        raise MalformedMessage(f"bad array in msgpack extension: dtype {dtype}, shape {shape}")
    # Copy out of the message buffer so callers get ordinary writable arrays.
    array = np.frombuffer(data, dtype, count, offset).reshape(shape).copy()
    return array[()] if code == EXT_SCALAR else array


_packer_options = {"default": _default, "use_bin_type": True}


def encode(obj: Any) -> bytes:
    """msgpack bytes of ``obj`` (dicts, lists, str, numbers, bytes, numpy arrays and scalars)."""
    encoded: bytes = msgpack.packb(obj, **_packer_options)  # (msgpack has no type hints)
    return encoded


def decode(data: bytes | bytearray | memoryview) -> Any:
    """The object encoded in ``data``; raises :class:`MalformedMessage` for anything invalid."""
    return _unpack(data, _ext_hook)


def decode_small_arrays(data: bytes, max_bytes: int) -> Any:
    """:func:`decode`, with each array whose encoding is longer than ``max_bytes`` left as None:
    for readers of a reply's small fields (a position) that have no use for its images."""

    def small_only(code: int, payload: bytes) -> Any:
        return None if len(payload) > max_bytes else _ext_hook(code, payload)

    return _unpack(data, small_only)


def _unpack(data: bytes | bytearray | memoryview, ext_hook: Callable[[int, bytes], Any]) -> Any:
    with _malformed_as_error():
        return msgpack.unpackb(data, ext_hook=ext_hook, raw=False)


@contextlib.contextmanager
def _malformed_as_error() -> Iterator[None]:
    """msgpack's and the array hook's complaints as :class:`MalformedMessage`."""
    try:
        yield
    except MalformedMessage:
        raise
    except (ValueError, TypeError, msgpack.UnpackException) as error:
        raise MalformedMessage(
            f"body is not valid msgpack ({type(error).__name__}: {error})"
        ) from None


def decode_keeping_encoded(data: bytes, name: str) -> dict[str, Any]:
    """:func:`decode` of a map, except that the items of its array ``name`` stay msgpack
    encodings: a server passes them on (:func:`encode_with_encoded`) without copying their
    arrays out and back in."""
    unpacker = msgpack.Unpacker(ext_hook=_ext_hook, raw=False, max_buffer_size=len(data))
    unpacker.feed(data)
    decoded: dict[str, Any] = {}
    with _malformed_as_error():
        for _ in range(unpacker.read_map_header()):
            key = unpacker.unpack()
            if key != name:
                decoded[key] = unpacker.unpack()
                continue
            items = []
            for _ in range(unpacker.read_array_header()):
                start = unpacker.tell()
                unpacker.skip()
                items.append(data[start : unpacker.tell()])
            decoded[key] = items
    return decoded


def encode_with_encoded(fields: Mapping[str, Any], encoded: Mapping[str, bytes]) -> bytes:
    """:func:`encode` of the map ``fields``, with the values named in ``encoded`` given as
    their msgpack encodings already."""
    packer = msgpack.Packer(**_packer_options)
    out = [packer.pack_map_header(len(fields))]
    for key, value in fields.items():
        out.append(packer.pack(key))
        out.append(encoded[key] if key in encoded else packer.pack(value))
    return b"".join(out)


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
        first: np.generic = flat[0]  # (numpy types an array's items as Any)
        return first
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
