"""JSON Schemas of the protocol's messages, generated from the message dataclasses.

One source: a message's fields, their type hints and their ``metadata["schema"]`` (bounds,
descriptions) give its schema; the server's OpenAPI document and the conformance tests use
these. A msgpack map is described as a JSON object. Arrays are not JSON: a schema
``{"x-msgpack-ext": 1}`` stands for msgpack extension 1 (an ndarray), ``2`` for a numpy scalar
(see :mod:`multion_client.protocol`); generic JSON Schema tools ignore that keyword.

This module imports nothing of the protocol's, so the messages can use its pieces in their
fields' metadata.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any

from gymnasium import spaces

EXT_NDARRAY = 1
EXT_SCALAR = 2
EXTENSION_KEYWORD = "x-msgpack-ext"

NDARRAY: dict[str, Any] = {
    "description": "a numpy array as msgpack extension 1: u8 len(dtype) | dtype (ASCII, e.g. "
    "'<f4', '|u1') | u8 ndim | ndim × u64 little-endian dims | the C-order raw bytes",
    EXTENSION_KEYWORD: EXT_NDARRAY,
}
SCALAR: dict[str, Any] = {
    "description": "a numpy scalar as msgpack extension 2 (the layout of extension 1, 0-d)",
    EXTENSION_KEYWORD: EXT_SCALAR,
}
OBSERVATION: dict[str, Any] = {
    "type": "object",
    "description": "sensor name → value (the session's sensors; see its observation_space)",
    "additionalProperties": {"anyOf": [NDARRAY, SCALAR]},
}
SPACE: dict[str, Any] = {
    "type": "object",
    "description": "a Gymnasium space: {type: Box, low, high, shape, dtype} | {type: Discrete, "
    "n, start} | {type: Dict, spaces: {name: space}}; Box bounds are a scalar or an array",
    "required": ["type"],
    "properties": {"type": {"enum": ["Box", "Discrete", "Dict"]}},
}


def message_schema(message: type) -> dict[str, Any]:
    """The JSON Schema of a message dataclass's wire form (unknown fields are refused)."""
    hints = typing.get_type_hints(message)
    properties: dict[str, Any] = {}
    required = []
    for f in dataclasses.fields(message):
        if f.metadata.get("wire") is False:
            continue
        extra = f.metadata.get("schema", {})
        # an explicit anyOf replaces the type hint's schema (e.g. a list or an array extension)
        schema = {**({} if "anyOf" in extra else type_schema(hints[f.name])), **extra}
        if f.default is not dataclasses.MISSING:
            schema.setdefault("default", f.default)
        elif f.default_factory is dataclasses.MISSING:
            required.append(f.name)
        properties[f.name] = schema
    doc = (message.__doc__ or "").strip().split("\n\n")[0]
    return {
        "title": message.__name__,
        "description": " ".join(doc.split()),
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": False,
    }


def type_schema(hint: Any) -> dict[str, Any]:
    """The schema of a field's type hint (the types messages use)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return {"anyOf": [type_schema(a) for a in args]}
    if origin is list:
        return {"type": "array", "items": type_schema(args[0])}
    if origin is dict:
        return {"type": "object"}
    space = origin if origin is not None else hint
    if isinstance(space, type) and issubclass(space, spaces.Space):
        return dict(SPACE)
    simple = {bool: "boolean", int: "integer", float: "number", str: "string", type(None): "null"}
    if hint in simple:
        return {"type": simple[hint]}
    if hint is Any:
        return {}
    raise TypeError(f"no schema for the type {hint!r}")


def error_schema(codes: list[str]) -> dict[str, Any]:
    """The body of an error answer whose code is one of ``codes``."""
    return {
        "title": "Error",
        "type": "object",
        "required": ["error"],
        "additionalProperties": False,
        "properties": {
            "error": {
                "type": "object",
                "required": ["code", "message"],
                "additionalProperties": False,
                "properties": {
                    "code": {"enum": sorted(codes)},
                    "message": {"type": "string"},
                },
            }
        },
    }


def schema(description: str = "", **keywords: Any) -> dict[str, Any]:
    """Field metadata for a message field: its description and JSON Schema keywords."""
    extra = {"description": description} if description else {}
    return {"schema": {**extra, **keywords}}
