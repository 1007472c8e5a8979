"""Validate msgpack answers against the JSON Schemas of the OpenAPI document.

Answers are decoded without the array hook, so an array stays a ``msgpack.ExtType`` and the
schema keyword ``x-msgpack-ext`` checks its extension code.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import msgpack
from jsonschema import Draft202012Validator, ValidationError, validators

from multion_client.schema import EXTENSION_KEYWORD


def _extension(
    validator: Any, code: int, instance: Any, schema: dict[str, Any]
) -> Iterator[ValidationError]:
    if not (isinstance(instance, msgpack.ExtType) and instance.code == code):
        yield ValidationError(f"{instance!r:.60} is not msgpack extension {code}")


WireValidator = validators.extend(Draft202012Validator, {EXTENSION_KEYWORD: _extension})


def raw_decode(content: bytes) -> Any:
    """The msgpack body with arrays left as ``ExtType``."""
    return msgpack.unpackb(content, raw=False)


def problems(schema: dict[str, Any], instance: Any) -> list[str]:
    """Where ``instance`` breaks ``schema`` (empty when it conforms)."""
    return [
        f"{'/'.join(map(str, e.absolute_path))}: {e.message}"
        for e in WireValidator(schema).iter_errors(instance)
    ]


def operation(document: dict[str, Any], method: str, path: str) -> dict[str, Any]:
    """The OpenAPI operation that serves ``method path`` (path parameters match any segment)."""
    for template, operations in document["paths"].items():
        parts, wanted = template.split("/"), path.split("/")
        if len(parts) == len(wanted) and all(
            p == w or p.startswith("{") for p, w in zip(parts, wanted, strict=True)
        ):
            return operations[method.lower()]
    raise AssertionError(f"{method} {path} is not documented")
