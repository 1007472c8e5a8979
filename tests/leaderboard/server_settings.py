"""The leaderboard settings every test server runs with, whether a ``multion serve``
subprocess (``conftest.start_server``) or in the test process (``in_process``)."""

from __future__ import annotations

LEADERBOARD: dict[str, float | bool] = {
    "token_cache_s": 0.0,  # tokens are checked at every request
    "expire_interval_s": 0.2,
    "warm_up": False,  # only the phases a test plays are generated
    "picture_interval_s": 0.5,  # run pictures soon after a run ends
}
MAX_REQUEST_BYTES = 65536


def leaderboard_env() -> dict[str, str]:
    """:data:`LEADERBOARD` as a ``multion serve`` subprocess reads it: environment variables."""
    return {
        f"MULTION_LEADERBOARD_{name.upper()}": str(value).lower()
        for name, value in LEADERBOARD.items()
    }
