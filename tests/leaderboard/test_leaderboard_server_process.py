"""The leaderboard's server process never loads the simulator (issue 45): its routes and pages
run in one process; hidden episodes are sampled, pictures drawn and films made in helper
processes, and runs are stepped by the spawned workers."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from multion.leaderboard.storage import Database, add_team

SERVE_RUN = """
import json, sys
from fastapi.testclient import TestClient
from multion.api.app import create_app
from multion.api.settings import ServerSettings
from multion.leaderboard.app import LeaderboardExtension
from multion.leaderboard.settings import LeaderboardSettings
from multion_client.protocol import CONTENT_TYPE, decode, encode
from multion_client.run_protocol import RUNS_PATH, CreateRun, RunStep, StartEpisode, run_path

challenge_file, database, token = json.loads(sys.stdin.read())
leaderboard = LeaderboardSettings(challenge=challenge_file, database=database, warm_up=False,
                                  token_cache_s=0)
headers = {"authorization": "Bearer " + token, "content-type": CONTENT_TYPE}
app = create_app(ServerSettings(workers=1, idle_timeout_s=600), [LeaderboardExtension(leaderboard)])

def post(client, path, body):
    answer = client.post(path, content=encode(body), headers=headers)
    assert answer.status_code < 300, (path, answer.status_code, answer.content[:300])
    return decode(answer.content)

with TestClient(app) as client:
    page = client.get("/leaderboard")
    assert page.status_code == 200, page.text[:300]
    run = post(client, RUNS_PATH, CreateRun("1-on", "minival", "probe", sensors=["gps"]).to_wire())
    started = post(client, run_path(run["run_id"], "episodes"), StartEpisode(0).to_wire())
    stepped = post(client, run_path(run["run_id"], "step"), RunStep(0, 1, 1).to_wire())
    run_page = client.get("/leaderboard/runs/" + run["run_id"])
    assert run_page.status_code == 200, run_page.text[:300]
    loaded = sorted(sys.modules)
simulator = [m for m in loaded if m.split(".")[0] == "pybullet" or m.startswith("multion.sim")]
print(json.dumps({
    "simulator": simulator + [m for m in loaded if m == "multion.task.env"],
    "modules": len(loaded),
    "seq": stepped["seq"],
}))
"""


def test_the_leaderboard_server_process_loads_no_simulator(
    challenge_file: Path, tmp_path: Path
) -> None:
    """A fresh interpreter (so this test process's own imports don't count) builds the
    leaderboard app, serves the board, starts a run's first episode and steps it once, and
    serves the run's page: pybullet, multion.sim.* and multion.task.env stay out of it."""
    database = f"sqlite:///{tmp_path / 'results.db'}"
    db = Database.open(database)
    with db.sessions.begin() as session:
        token = add_team(session, "probe")[1]
    db.close()
    result = subprocess.run(
        [sys.executable, "-c", SERVE_RUN],
        input=json.dumps([str(challenge_file), database, token]),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    served = json.loads(result.stdout.strip().splitlines()[-1])
    assert served["seq"] == 1
    assert served["simulator"] == []  # the helpers and workers load them, never this process
