"""The shipped MultiON 2.0 challenge file: its tracks' own rules (5-ON, 3 distractors, FOUND
within 1.0 m, cylinders or everyday objects) are read, served, played, scored and shown."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import httpx
import numpy as np
import pytest

from multion.api.local_server import LocalServer
from multion.api.workers import WorkerReport
from multion.config.codec import env_config_from_dict
from multion.leaderboard.app import renderer_problem
from multion.leaderboard.challenge import ChallengeError
from multion.leaderboard.challenge_file import challenge_from_dict, load_challenge
from multion.leaderboard.hidden import generate_hidden_episodes
from multion.leaderboard.storage import Database, add_team
from multion.sim.gl.context import gl_unavailable_reason
from multion_client.client import Client
from multion_client.run import RunEnv

EXAMPLE = (
    Path(__file__).resolve().parents[2]
    / "server" / "multion" / "leaderboard" / "examples" / "multion-2.0.toml"
)  # fmt: skip
SECRET = {"MULTION_CHALLENGE_SECRET": "multion-2-test-secret-0123456789"}


def small_copy(directory: Path) -> Path:
    """The example with its sizes shrunk for a test (episodes, houses, camera, step limit);
    every rule of its tracks unchanged."""
    text = EXAMPLE.read_text()
    for before, after in [
        ("episodes = 1000", "episodes = 2"), ("episodes = 30", "episodes = 2"),
        ("houses = 18", "houses = 1"), ("houses = 3", "houses = 1"),
        ("width = 256, height = 256", "width = 32, height = 32"),
        ("max_steps = 2500", "max_steps = 25"),
    ]:  # fmt: skip
        assert before in text
        text = text.replace(before, after)
    if gl_unavailable_reason() is not None and os.environ.get("MULTION_REQUIRE_EGL") != "1":
        # no OpenGL here (the server would refuse the gl tracks): the rules do not change
        text = text.replace('renderer = "gl"', 'renderer = "tiny"')
    path = directory / "multion-2.0-small.toml"
    path.write_text(
        f"{text}\n".replace(
            'secret_env = "MULTION_CHALLENGE_SECRET"',
            f'secret = "{SECRET["MULTION_CHALLENGE_SECRET"]}"',
        )
    )
    return path


def test_the_example_states_the_2022_rules() -> None:
    challenge = load_challenge(EXAMPLE, SECRET)
    assert [t.name for t in challenge.tracks] == ["5-on-cylinders", "5-on-objects"]
    for track in challenge.tracks:
        config = env_config_from_dict(track.env_config(track.phases[0]))
        assert config.task.num_goals == 5 and config.task.num_distractors == 3
        assert config.task.success_distance == 1.0 and config.task.max_steps == 2500
        assert config.camera.width == 256 and config.camera.hfov_deg == 79.0
        assert config.camera.renderer == "gl"
    assert [t.goal_set for t in challenge.tracks] == ["colours", "objects"]
    described = challenge.describe()["tracks"][1]
    assert described["num_distractors"] == 3 and described["success_distance"] == 1.0
    assert described["goal_set"] == "objects" and described["found_budget"] == 0


def test_track_rules_are_checked_with_their_ranges() -> None:
    def track(**rules: object) -> dict[str, object]:
        return {"name": "t", "num_goals": 5, **rules,
                "phases": [{"name": "minival", "episodes": 1, "houses": 1}]}  # fmt: skip

    def load(**rules: object) -> None:
        challenge_from_dict(
            {"challenge": {"name": "c", "secret": "s" * 32}, "tracks": [track(**rules)]}, {}
        )

    load(num_distractors=3, success_distance=1.0, found_budget=2, goal_set="shapes")
    with pytest.raises(ChallengeError, match=r"num_distractors must be in 0\.\.3"):
        load(num_distractors=4)
    with pytest.raises(ChallengeError, match="success_distance"):
        load(success_distance=0)
    with pytest.raises(ChallengeError, match="success_distance must be int or float"):
        load(success_distance="1")
    with pytest.raises(ChallengeError, match="goal_set"):
        load(goal_set="animals")
    with pytest.raises(ChallengeError, match="found_budget"):
        load(found_budget=-1)
    with pytest.raises(ChallengeError, match="num_distractors"):
        load(num_distractors="3")


def test_create_play_score_and_show(tmp_path: Path, launch: Callable[..., LocalServer]) -> None:
    challenge_file = small_copy(tmp_path)
    challenge = load_challenge(challenge_file)
    track = challenge.tracks[1]
    hidden = generate_hidden_episodes(challenge, track, track.phases[0])
    assert all(e.num_goals == 5 and len(e.distractors) == 3 for e in hidden)
    database = f"sqlite:///{tmp_path / 'results.db'}"
    db = Database.open(database)
    with db.sessions.begin() as session:
        token = add_team(session, "habitat-2022")[1]
    db.close()
    server = launch(challenge_file, database)
    try:
        rng = np.random.default_rng(0)
        for name in ("5-on-cylinders", "5-on-objects"):
            env = RunEnv(server.url, name, "minival", "random 2.0", token=token)
            played = 0
            while not env.run_done:
                env.reset()
                played += 1
                done = False
                while not done:
                    action = int(rng.choice([1, 1, 2, 3, 0]))
                    _, _, terminated, truncated, info = env.step(action)
                    done = terminated or truncated
                assert "distractor_founds" in info["metrics"]  # minival: per-episode feedback
            assert played == 2
            status = env.status()
            assert status.state == "finished" and status.results
            env.close()
        client = Client(server.url)
        tracks = {t["name"]: t for t in client.challenge()["tracks"]}
        client.close()
        assert tracks["5-on-objects"]["goal_set"] == "objects"
        assert tracks["5-on-cylinders"]["success_distance"] == 1.0
        page = httpx.get(f"{server.url}/leaderboard/rules", timeout=30).text
        assert "within 1.0 m" in page and "3 distractors per episode" in page
        assert "8 everyday objects (teddy bear" in page and "8 coloured cylinders" in page
    finally:
        server.stop()


def test_a_server_without_opengl_refuses_the_gl_tracks_at_start() -> None:
    challenge = load_challenge(EXAMPLE, SECRET)
    problem = renderer_problem(challenge, WorkerReport(pid=1, gl_unavailable="no EGL display"))
    assert problem is not None
    assert "5-on-cylinders, 5-on-objects" in problem and "no EGL display" in problem
    assert "apt-get install libegl1 libgl1" in problem
    assert renderer_problem(challenge, WorkerReport(pid=1, renderer_auto="gl")) is None
