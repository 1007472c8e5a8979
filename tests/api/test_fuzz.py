"""Property-based fuzzing of a real server (``multion serve`` in a subprocess, over HTTP).

Hypothesis generates session configs, reset seeds and options, and action lists, inside and
outside the ranges the configs declare (taken from the config dataclasses, so new fields are
fuzzed too). Whatever it sends: never a 5xx, never a simulator worker death, worker memory
under its limit. Scenes are the small room (inline episodes), so that an example costs
milliseconds rather than the seconds a house takes to build.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from multion.api.local_server import LocalServer
from multion.config.ranges import Range, field_ranges
from multion.config.task import EnvConfig
from multion_client.protocol import CONTENT_TYPE, decode, encode, session_path

WORKER_MB = 3072
ANSWERS: Counter[int] = Counter()


@pytest.fixture(scope="module")
def server() -> Iterator[LocalServer]:
    options = ["--worker-memory-mb", str(WORKER_MB), "--max-sessions", "8"]
    with LocalServer(workers=2, options=options) as local:
        yield local
    print(f"\nfuzzing sent {ANSWERS.total()} requests; answers by status: {dict(ANSWERS)}")


@pytest.fixture(scope="module")
def http(server: LocalServer) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=server.url, timeout=120) as client:
        yield client


def send(http: httpx.Client, method: str, path: str, body: Any = None) -> tuple[int, Any]:
    content = None if body is None else encode(body)
    response = http.request(method, path, content=content, headers={"content-type": CONTENT_TYPE})
    ANSWERS[response.status_code] += 1
    assert response.status_code < 500, (method, path, body, response.content[:500])
    return response.status_code, decode(response.content)


# ---------------------------------------------------------------------- strategies
def values_around(spec: Range) -> st.SearchStrategy[Any]:
    """Values inside the range, on its ends, just outside, and of the wrong kind."""
    if spec.choices is not None:
        return st.one_of(st.sampled_from(spec.choices), st.text(max_size=12))
    low = -1e6 if spec.low is None else spec.low
    high = 1e6 if spec.high is None else spec.high
    inside = (
        st.integers(int(math.ceil(low)), int(math.floor(high)))
        if spec.integer
        else st.floats(low, high, allow_nan=False)
    )
    edges = st.sampled_from([low, high, low - 1, high + 1, -(2**40), 2**40, 0])
    wrong = st.sampled_from([math.nan, math.inf, "1", None, True, [1]])
    return st.one_of(inside, inside, edges, wrong)


def section_values(config_class: type) -> st.SearchStrategy[dict[str, Any]]:
    fields = {name: values_around(spec) for name, spec in field_ranges(config_class)}
    return st.fixed_dictionaries({}, optional=fields)


# Sizes kept where an example stays cheap (the ranges' far ends are fuzzed by the edges above,
# and the memory estimate refuses what would not fit); rooms are small, houses are not used.
SECTIONS = {
    "task": section_values(type(EnvConfig().task)),
    "agent": section_values(type(EnvConfig().agent)),
    "camera": section_values(type(EnvConfig().camera)),
    "navgrid": section_values(type(EnvConfig().navgrid)),
    "maps": section_values(type(EnvConfig().maps)),
}
SENSORS = st.lists(
    st.sampled_from([*EnvConfig().sensors, "oracle_map", "gps", "compass", "goal_onehot", "x"]),
    max_size=5,
)


@st.composite
def configs(draw: st.DrawFn, episodes: list[dict[str, Any]]) -> dict[str, Any]:
    config: dict[str, Any] = {
        name: draw(section) for name, section in SECTIONS.items() if draw(st.booleans())
    }
    camera = config.setdefault("camera", {})
    for side in ("width", "height"):  # rendering cost: keep valid sizes small
        if isinstance(camera.get(side), int) and 64 < camera[side] <= 1024:
            camera[side] = draw(st.sampled_from([64, camera[side]]))
        camera.setdefault(side, 32)
    task = config.setdefault("task", {})
    task["num_goals"] = len(episodes[0]["goals"])
    if isinstance(task.get("max_steps"), int) and task["max_steps"] > 50:
        task["max_steps"] = 50
    if draw(st.booleans()):
        config["sensors"] = draw(SENSORS)
    config["episodes"] = episodes
    return config


SEEDS = st.one_of(
    st.none(),
    st.integers(0, 2**40),
    st.integers(-5, 2**64 - 1),  # msgpack's integers end at 2**64 - 1
    st.floats(allow_nan=True),
    st.text(max_size=3),
)
OPTIONS = st.one_of(
    st.none(),
    st.fixed_dictionaries(
        {},
        optional={
            "episode_index": st.one_of(st.integers(-3, 10), st.text(max_size=2)),
            "episode_id": st.text(max_size=8),
            "bogus": st.integers(-(2**63), 2**64 - 1),
        },
    ),
)
VALID_ACTION = st.integers(0, 3)
MOTION = st.integers(1, 3)  # no FOUND: it would end the episode
ACTION = st.one_of(
    VALID_ACTION,
    VALID_ACTION,
    VALID_ACTION,
    st.integers(-2, 6),
    st.floats(allow_nan=True),
    st.booleans(),
    st.none(),
    st.text(max_size=2),
    st.integers(0, 3).map(np.int64),
)


# ---------------------------------------------------------------------- properties
@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_fuzzed_configs_never_break_the_server(
    http: httpx.Client, small_config: dict[str, Any], data: st.DataObject
) -> None:
    config = data.draw(configs(small_config["episodes"]))
    num_envs = data.draw(st.sampled_from([1, 1, 2, 0, -1, 65, "2"]))
    status, body = send(http, "POST", "/v1/sessions", {"config": config, "num_envs": num_envs})
    if status != 201:
        assert 400 <= status < 500 and body["error"]["message"]
        return
    sid = body["session_id"]
    try:
        n = body["num_envs"]
        seeds = data.draw(st.lists(SEEDS, min_size=n, max_size=n))
        status, _ = send(http, "POST", session_path(sid, "reset"), {"seeds": seeds})
        for _ in range(data.draw(st.integers(0, 6))):
            actions = data.draw(st.lists(ACTION, min_size=n, max_size=n))
            send(http, "POST", session_path(sid, "step"), {"actions": actions})
    finally:
        send(http, "DELETE", session_path(sid))


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(
    seeds=st.one_of(st.lists(SEEDS, min_size=2, max_size=2), st.lists(SEEDS, max_size=3)),
    options=st.one_of(st.just([]), st.lists(OPTIONS, min_size=2, max_size=2), st.lists(OPTIONS)),
    steps=st.lists(
        st.one_of(
            st.lists(MOTION, min_size=2, max_size=2),
            st.lists(MOTION, min_size=2, max_size=2),
            st.lists(ACTION, min_size=2, max_size=2),
            st.lists(ACTION, max_size=3),
        ),
        max_size=8,
    ),
)
def test_fuzzed_resets_and_steps_never_break_the_server(
    session: str, http: httpx.Client, seeds: list[Any], options: list[Any], steps: list[Any]
) -> None:
    status, _ = send(
        http, "POST", session_path(session, "reset"), {"seeds": seeds, "options": options}
    )
    if status != 200:
        assert send(http, "POST", session_path(session, "reset"), {})[0] == 200
    for actions in steps:
        send(http, "POST", session_path(session, "step"), {"actions": actions})


@pytest.fixture(scope="module")
def session(http: httpx.Client, small_config: dict[str, Any]) -> Iterator[str]:
    config = {**small_config, "task": {**small_config["task"], "max_steps": 20}}
    status, body = send(http, "POST", "/v1/sessions", {"config": config, "num_envs": 2})
    assert status == 201
    yield body["session_id"]
    send(http, "DELETE", session_path(body["session_id"]))


def test_after_fuzzing_no_worker_died_and_memory_stayed_bounded(http: httpx.Client) -> None:
    status, health = send(http, "GET", "/v1/health")
    assert health["workers_replaced"] == 0 and health["status"] == "ok"
    for worker in health["workers"]:
        with open(f"/proc/{worker['pid']}/status") as status_file:
            peak = next(int(r.split()[1]) for r in status_file if r.startswith("VmHWM:"))
        assert peak < WORKER_MB * 1024
    # the fuzzing reached the simulator, not only the validation
    assert ANSWERS[201] >= 5 and ANSWERS[200] >= 100 and ANSWERS[422] >= 5, ANSWERS
