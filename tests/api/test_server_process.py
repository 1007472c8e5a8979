"""The server process never loads the simulator (issue 45): its app, sessions and routers run in
one process and PyBullet only in the spawned workers, which report the renderer they resolve."""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

SERVE_SESSIONS = """
import json, sys
from fastapi.testclient import TestClient
from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion_client.protocol import CONTENT_TYPE, RENDERER_HEADER, decode, encode

def call(client, method, path, body=None):
    content = None if body is None else encode(body)
    answer = client.request(method, path, content=content, headers={"content-type": CONTENT_TYPE})
    assert answer.status_code < 300, (path, answer.status_code, answer.content[:300])
    return answer

configs = json.loads(sys.stdin.read())
renderers, steps, fields = [], [], []
with TestClient(create_app(ServerSettings(workers=1, idle_timeout_s=600))) as client:
    spec = decode(call(client, "GET", "/v1/spec").content)
    for config in configs:
        create = {"config": config, "num_envs": 1, "auto_reset": False}
        created = call(client, "POST", "/v1/sessions", create)
        info = decode(created.content)
        fields.append(sorted(info))
        path = "/v1/sessions/" + info["session_id"]
        call(client, "POST", path + "/reset", {"seeds": [0], "options": []})
        stepped = call(client, "POST", path + "/step", {"actions": [1]})
        steps.append(len(decode(stepped.content)["rewards"]))
        call(client, "DELETE", path)
        renderers.append(created.headers.get(RENDERER_HEADER))
    loaded = sorted(sys.modules)
simulator = [m for m in loaded if m.split(".")[0] == "pybullet" or m.startswith("multion.sim")]
print(json.dumps({
    "simulator": simulator + [m for m in loaded if m == "multion.task.env"],
    "spec_renderer": spec["renderer"],
    "metadata": spec["metadata"],
    "session_renderers": renderers,
    "session_fields": fields,
    "steps": steps,
}))
"""


def serve_sessions(configs: list[dict[str, Any]]) -> dict[str, Any]:
    """Run the app in a fresh interpreter (so this test process's own imports don't count): its
    worker pool started, one session per config created, reset, stepped once and closed."""
    result = subprocess.run(
        [sys.executable, "-c", SERVE_SESSIONS],
        input=json.dumps(configs),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    answer: dict[str, Any] = json.loads(result.stdout.strip().splitlines()[-1])
    return answer


def test_the_server_process_loads_no_simulator_while_it_serves_sessions(
    small_config: dict[str, Any],
) -> None:
    auto = {**small_config, "camera": {"width": 32, "height": 32, "renderer": "auto"}}
    served = serve_sessions([small_config, auto])
    assert served["steps"] == [1, 1]
    assert served["simulator"] == []  # pybullet, multion.sim.*, multion.task.env: workers only
    # the spec's renderer comes from the worker's ready message, and each session's from the
    # worker that created its environments
    renderer = served["spec_renderer"]
    assert renderer["auto"] in ("tiny", "gl")
    assert (renderer["auto"] == "tiny") == (renderer["gl_unavailable"] is not None)
    assert served["session_renderers"] == ["tiny", renderer["auto"]]  # tiny: the default
    # the renderer travels in a header: the body keeps the fields every client accepts (clients
    # refuse unknown fields, so a new field would break those installed before it)
    old_fields = sorted(
        ["session_id", "num_envs", "auto_reset", "observation_space", "action_space"]
    )
    assert served["session_fields"] == [old_fields, old_fields]
    assert served["metadata"] == {"render_modes": ["rgb_array"], "render_fps": 10}
