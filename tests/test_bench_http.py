"""``multion bench --only http``'s parts: which renderers it measures, and one env's row with the
CPU of each process on the remote path."""

from __future__ import annotations

import pytest

from multion.api.local_server import LocalServer
from multion_agents.bench import http
from multion_agents.bench.http import _single_env, http_renderers


def test_renderers_follow_the_flag(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(http, "why_not_gl", lambda: None)
    assert http_renderers("all") == (("tiny", "gl"), None)
    assert http_renderers("gl") == (("gl",), None)
    assert http_renderers("tiny") == (("tiny",), None)
    monkeypatch.setattr(http, "why_not_gl", lambda: "no EGL display")
    assert http_renderers("all") == (("tiny",), None)
    renderers, why_not = http_renderers("gl")
    assert renderers == () and why_not is not None and "no EGL display" in why_not


def test_one_env_row_has_the_rates_and_each_process_cpu() -> None:
    with LocalServer(workers=1) as server:
        row = _single_env(server, 32, "tiny", 60, lambda text: None)
    assert row["in_process_sps"] > 0 and row["http_sps"] > 0
    assert row["ratio"] == pytest.approx(row["http_sps"] / row["in_process_sps"])
    for key in ("client_cpu_ms", "http_cpu_ms", "worker_cpu_ms", "in_process_cpu_ms"):
        assert row[key] > 0, key
    # the worker simulates what the in-process env simulates: read from the right process, its
    # CPU is of the same order (0 or a tiny share if it were the wrong one)
    assert row["worker_cpu_ms"] > 0.3 * row["in_process_cpu_ms"], row
