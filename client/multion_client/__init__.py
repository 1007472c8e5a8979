"""MultiON client: the wire protocol and Gymnasium-style remote environments.

Light on purpose: it needs numpy, msgpack and gymnasium, never PyBullet, torch or FastAPI.
``Client``, ``RemoteEnv`` and ``RemoteVectorEnv`` are imported on first use, so the server and
simulator can import ``multion_client.constants`` without pulling in the HTTP client.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["API_VERSION", "Client", "RemoteEnv", "RemoteVectorEnv", "RunEnv"]

_HOMES = {
    "API_VERSION": "multion_client.protocol",
    "Client": "multion_client.client",
    "RemoteEnv": "multion_client.env",
    "RemoteVectorEnv": "multion_client.vector",
    "RunEnv": "multion_client.run",
}


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module 'multion_client' has no attribute {name!r}")
