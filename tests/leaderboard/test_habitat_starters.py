"""Issue 42 parts 3, 4 and 6: the MultiON challenge starters' ``evaluate.py`` (3dlg-hcvc/
multion-challenge, tags ``chal-2021`` and ``chal_2022``; written again here in our own words,
same shapes) run as scripts with only ``import habitat`` changed; batched agents keep a lane at
one position for the whole run; a crashed or stopped agent's run is abandoned on the way out,
and ``MULTION_RUN_ID`` resumes one."""

from __future__ import annotations

import copy
import os
import pickle
import re
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import multion_client.habitat_compat as habitat
from multion.api.local_server import LocalServer
from multion.config.sim import AgentConfig, CameraConfig
from multion_client.habitat_agent import play_batched
from multion_client.habitat_config import AGENT_DEFAULTS, CAMERA_DEFAULTS
from multion_client.run import RunEnv

CHANGED_LINE = "import multion_client.habitat_compat as habitat"

STARTER_2021 = f"""
import sys
sys.path.insert(0, "")
import numpy as np
{CHANGED_LINE}
from habitat.core.challenge import Challenge


class Wanderer(habitat.Agent):
    def __init__(self):
        self.choices = np.array([0, 1, 2, 3])

    def reset(self):
        pass

    def act(self, observations, not_done_masks):
        return [np.random.choice(self.choices) for _ in range(len(observations))]


if __name__ == "__main__":
    Challenge().submit(Wanderer())
"""

STARTER_2022 = f"""
import sys
sys.path.insert(0, "")
import numpy as np
{CHANGED_LINE}


class Wanderer(habitat.Agent):
    def __init__(self, task_config: habitat.Config):
        self.choices = task_config.TASK.POSSIBLE_ACTIONS

    def reset(self):
        pass

    def act(self, observations):
        return {{"action": np.random.choice(self.choices)}}


if __name__ == "__main__":
    config = habitat.get_config("./configs/multinav_cyl.yaml")
    challenge = habitat.Challenge()
    challenge.submit(Wanderer(task_config=config))
"""


@pytest.fixture()
def settings(server: LocalServer, new_team: Callable[[str], str]) -> dict[str, str]:
    """The variables a participant exports before ``python evaluate.py``."""
    return {
        "MULTION_SERVER": server.url,
        "MULTION_TOKEN": new_team(f"starter-{np.random.default_rng().integers(10**9)}"),
        "MULTION_TRACK": "1-on",
        "MULTION_PHASE": "minival",
        "MULTION_METHOD": "starter",
    }


def run_script(
    tmp_path: Path, source: str, settings: Mapping[str, str]
) -> subprocess.CompletedProcess[str]:
    script = tmp_path / "evaluate.py"
    script.write_text(textwrap.dedent(source))
    env = {k: v for k, v in os.environ.items() if not k.startswith("MULTION_")}
    return subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env={**env, **settings, "OMP_NUM_THREADS": "1"},
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip


@pytest.mark.parametrize("source", [STARTER_2021, STARTER_2022], ids=["chal-2021", "chal_2022"])
def test_a_starter_runs_with_only_the_import_changed(
    source: str, settings: dict[str, str], tmp_path: Path
) -> None:
    done = run_script(tmp_path, source, settings)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    # what `multion submit` prints: the run as it starts (all 3 episodes at once for the 2021
    # form: its default 4 lanes, capped at the phase's 3), then its end and results
    lanes = "3 at once" if source is STARTER_2021 else "1 at once"
    assert lines[0].startswith("run ") and f"3 episodes, {lanes}" in lines[0]
    run_id = lines[0].split()[1].rstrip(":")
    assert f"MULTION_RUN_ID={run_id}" in lines[0]
    assert lines[1] == f"run {run_id}: finished, 3/3 episodes completed"
    assert any(line.split()[0] == "ppl" and line.endswith("(ranking)") for line in lines[2:])


def test_get_config_is_the_tracks(
    settings: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    for name, value in settings.items():
        monkeypatch.setenv(name, value)
    config = habitat.get_config(["no/such/file.yaml"])
    # the reference's actions, in its order (chal_2022 configs/multinav_real.yaml, TASK)
    assert config.TASK.POSSIBLE_ACTIONS == ["FOUND", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT"]
    assert config["TASK"]["SUCCESS_DISTANCE"] == 1.5 and config.ENVIRONMENT.MAX_EPISODE_STEPS == 40
    rgb = config.SIMULATOR.RGB_SENSOR
    assert (rgb.WIDTH, rgb.HEIGHT, rgb.HFOV) == (32, 32, 79.0)  # the track's camera, then defaults
    assert config.SIMULATOR.DEPTH_SENSOR.MAX_DEPTH == 10.0 and config.SIMULATOR.TURN_ANGLE == 30.0
    assert config.TASK.SENSORS == ["MULTI_OBJECT_GOAL_SENSOR", "COMPASS_SENSOR", "GPS_SENSOR"]
    assert config.DATASET.SPLIT == "minival" and config.MULTION.NUM_GOALS == 1
    # frozen as habitat's; defrost, set, clone, copy and pickle as a yacs CfgNode
    with pytest.raises(AttributeError, match="frozen"):
        config.TASK.SUCCESS_DISTANCE = 3.0
    with pytest.raises(AttributeError, match="no key 'NO_SUCH'"):
        _ = config.TASK.NO_SUCH
    copies = [config.clone(), copy.deepcopy(config), pickle.loads(pickle.dumps(config))]
    assert all(c == config and c.is_frozen() and c.TASK.is_frozen() for c in copies)
    config.defrost()
    config.TASK.SUCCESS_DISTANCE = 3.0
    config.merge_from_list(["ENVIRONMENT.MAX_EPISODE_STEPS", "500"])
    assert config.TASK.SUCCESS_DISTANCE == 3.0 and config.ENVIRONMENT.MAX_EPISODE_STEPS == 500
    with pytest.raises(ValueError, match="no key 'TASK.NOPE'"):
        config.merge_from_list(["TASK.NOPE", 1])
    monkeypatch.delenv("MULTION_TRACK")
    with pytest.raises(ValueError, match="set MULTION_TRACK"):
        habitat.get_config("configs/multinav_real.yaml")


def test_the_client_defaults_are_the_servers() -> None:
    camera, agent = CameraConfig(), AgentConfig()
    assert {k: getattr(camera, k) for k in CAMERA_DEFAULTS} == CAMERA_DEFAULTS
    assert {k: getattr(agent, k) for k in AGENT_DEFAULTS} == AGENT_DEFAULTS


def test_only_the_challenge_path_is_taken() -> None:
    """``habitat.core.challenge`` names the compat layer; ``habitat`` itself is left alone, so a
    real habitat installed beside still imports as itself."""
    from habitat.core.challenge import Challenge  # type: ignore[import-not-found]

    assert Challenge is habitat.Challenge
    assert "habitat" not in sys.modules or sys.modules["habitat"] is not habitat


# ---------------------------------------------------------------------- lanes keep positions
class ScriptedLane:
    """A lane that plays given episodes of given lengths; its observation carries the episode
    number in ``gps`` (forward), so an agent can say which episode it was shown."""

    def __init__(self, episodes: list[tuple[int, int]]) -> None:
        self.todo = list(episodes)  # (episode number, steps)
        self.episode, self.left = -1, 0

    @property
    def run_done(self) -> bool:
        return not self.todo and self.left == 0

    def obs(self) -> dict[str, np.ndarray]:
        return {"gps": np.array([self.episode, 0.0], dtype=np.float32)}

    def reset(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        self.episode, self.left = self.todo.pop(0)
        return self.obs(), {}

    def step(self, action: int) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        assert self.left > 0, "stepped a lane with no episode in progress"
        self.left -= 1
        return self.obs(), 0.0, self.left == 0, False, {}


class RecurrentRecorder(habitat.Agent):
    """A 2021-style agent with per-position memory: the episode it believes each position is
    in (set where the mask is 0), checked against the episode it is shown."""

    def __init__(self) -> None:
        self.memory: dict[int, int] = {}
        self.seen: dict[int, list[int]] = {}
        self.crossed: list[tuple[int, int, int]] = []

    def reset(self) -> None:
        self.memory.clear()

    def act(self, observations, not_done_masks):
        for k, (obs, mask) in enumerate(zip(observations, not_done_masks, strict=True)):
            shown = int(obs["gps"][0])
            if mask[0] == 0.0:
                self.memory[k] = shown
            elif self.memory.get(k) != shown:
                self.crossed.append((k, self.memory.get(k, -1), shown))
            self.seen.setdefault(k, []).append(shown)
        return [1] * len(observations)


def test_a_lane_keeps_its_position_when_the_middle_one_ends() -> None:
    # lane 1 (episode B = 1) ends first; lanes 0 and 2 go on (A = 0 then D = 3; C = 2)
    lanes = [ScriptedLane([(0, 5), (3, 4)]), ScriptedLane([(1, 2)]), ScriptedLane([(2, 7)])]
    agent = RecurrentRecorder()
    play_batched(
        agent, lanes, lambda obs: habitat.habitat_observations(obs, habitat.DepthRange({}))
    )
    assert agent.crossed == []  # before: C continued at position 1 with B's memory
    assert set(agent.seen[1]) == {1} and set(agent.seen[2]) == {2}
    assert agent.seen[0] == [0] * 5 + [3] * 4
    assert all(lane.run_done for lane in lanes)


# ---------------------------------------------------------------------- crashes and resumes
class CrashingAgent(habitat.Agent):
    def __init__(self, after: int) -> None:
        self.after, self.steps = after, 0

    def reset(self) -> None:
        pass

    def act(self, observations):
        self.steps += 1
        if self.steps > self.after:
            raise RuntimeError("a bug in the agent")
        return "TURN_LEFT"


def test_a_crashing_agent_abandons_its_run(
    settings: dict[str, str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    for name, value in settings.items():
        monkeypatch.setenv(name, value)
    with pytest.raises(RuntimeError, match="a bug"):
        habitat.Challenge().submit(CrashingAgent(after=3))
    out, err = capsys.readouterr()
    run_id = out.split()[1].rstrip(":")
    assert f"run {run_id}: abandoned after RuntimeError" in err
    status = RunEnv(settings["MULTION_SERVER"], token=settings["MULTION_TOKEN"], run_id=run_id)
    assert (status.status().state, status.status().end_reason) == ("ended", "abandoned")


def test_sigterm_abandons_the_run(settings: dict[str, str], tmp_path: Path) -> None:
    marker = tmp_path / "acting"
    source = f"""
    import time
    {CHANGED_LINE}

    class Slow(habitat.Agent):
        def reset(self):
            pass

        def act(self, observations):
            open({str(marker)!r}, "w").close()
            time.sleep(0.2)
            return 2

    habitat.Challenge().submit(Slow())
    """
    script = tmp_path / "evaluate.py"
    script.write_text(textwrap.dedent(source))
    env = {k: v for k, v in os.environ.items() if not k.startswith("MULTION_")}
    process = subprocess.Popen(
        [sys.executable, str(script)], env={**env, **settings, "OMP_NUM_THREADS": "1"},
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not marker.exists() and time.monotonic() < deadline and process.poll() is None:
            time.sleep(0.1)
        assert marker.exists(), "the agent never acted"
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 128 + signal.SIGTERM, err[-2000:]
    run_id = out.split()[1].rstrip(":")
    assert f"run {run_id}: abandoned after SystemExit" in err
    env_ = RunEnv(settings["MULTION_SERVER"], token=settings["MULTION_TOKEN"], run_id=run_id)
    assert env_.status().end_reason == "abandoned"


class CountingAgent(habitat.Agent):
    def __init__(self) -> None:
        self.episodes = 0

    def reset(self) -> None:
        self.episodes += 1

    def act(self, observations):
        return 0  # FOUND: each episode ends at once


def test_multion_run_id_resumes_a_run(
    settings: dict[str, str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    started = RunEnv(settings["MULTION_SERVER"], "1-on", "minival", "resumed",
                     token=settings["MULTION_TOKEN"])  # fmt: skip
    started.reset()
    started.step(0)  # episode 0 played; then the process "died"
    started.close()
    monkeypatch.setenv("MULTION_SERVER", settings["MULTION_SERVER"])
    monkeypatch.setenv("MULTION_TOKEN", settings["MULTION_TOKEN"])
    for name in ("MULTION_TRACK", "MULTION_PHASE", "MULTION_METHOD"):
        monkeypatch.delenv(name, raising=False)  # a resumed run needs none of them
    monkeypatch.setenv("MULTION_RUN_ID", started.run_id)
    agent = CountingAgent()
    results = habitat.Challenge().submit(agent)
    assert agent.episodes == 2 and results  # episodes 1 and 2
    assert f"run {started.run_id}: finished" in capsys.readouterr().out


def test_the_guides_example_runs(settings: dict[str, str], tmp_path: Path) -> None:
    """docs/leaderboard.md's habitat example, as written, is an ``evaluate.py`` that plays a run."""
    guide = Path(__file__).resolve().parents[2] / "docs" / "leaderboard.md"
    blocks = re.findall(r"```python\n(.*?)```", guide.read_text(encoding="utf-8"), re.S)
    example = next(block for block in blocks if CHANGED_LINE in block)
    done = run_script(tmp_path, example, settings)
    assert done.returncode == 0, done.stderr[-3000:]
    assert re.search(r": finished, (\d+)/\1 episodes completed$", done.stdout.splitlines()[-5])
