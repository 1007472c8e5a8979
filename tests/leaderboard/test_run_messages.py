"""The run messages of the wire protocol: round trips and the refusals a server relies on."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces

from multion_client import errors
from multion_client.protocol import decode, encode
from multion_client.run_protocol import (
    CreateRun,
    RunInfo,
    RunObservation,
    RunStep,
    StartEpisode,
    run_path,
)


def roundtrip(message):
    return type(message).from_wire(decode(encode(message.to_wire())))


def test_messages_round_trip() -> None:
    create = CreateRun("3-on", "minival", "mine", ["rgb", "goal"], {"ego_size": 31},
                       "https://arxiv.org/abs/2012.03912", None)  # fmt: skip
    assert roundtrip(create) == create
    assert roundtrip(StartEpisode(4)) == StartEpisode(4)
    assert roundtrip(RunStep(1, 7, 2)) == RunStep(1, 7, 2)
    observation = RunObservation(0, 3, {"goal": np.int64(2)}, done=True, end_reason="success",
                                 metrics={"ppl": 0.5}, run_done=False)  # fmt: skip
    again = roundtrip(observation)
    assert again.end_reason == "success" and again.observation["goal"] == 2
    info = RunInfo("r", "3-on", "minival", 10, ["goal"], spaces.Dict({"goal": spaces.Discrete(8)}),
                   spaces.Discrete(4), {"step_timeout_s": 60.0})  # fmt: skip
    assert roundtrip(info).observation_space == info.observation_space
    assert run_path("abc", "step") == "/v1/runs/abc/step"


@pytest.mark.parametrize(
    ("cls", "body"),
    [
        (StartEpisode, {"episode": 0, "seed": 1}),
        (StartEpisode, {"episode": 0, "options": {"episode_index": 3}}),
        (StartEpisode, {"episode": 0, "episode_id": "val-3-on-00001"}),
        (RunStep, {"episode": 0, "seq": 1, "action": 1, "seeds": [1]}),
        (CreateRun, {"track": "3-on", "phase": "minival", "method": "m", "config": {}}),
    ],
)
def test_choosing_episodes_or_seeds_is_not_allowed(cls: type, body: dict) -> None:
    with pytest.raises(errors.NotAllowedInRun) as caught:
        cls.from_wire(body)
    assert caught.value.status == 403


@pytest.mark.parametrize(
    ("cls", "body", "error"),
    [
        (RunStep, {"episode": 0, "seq": 0, "action": 1}, errors.MalformedMessage),
        (RunStep, {"episode": 0, "seq": 1, "action": True}, errors.InvalidAction),
        (RunStep, {"episode": 0, "seq": 1, "action": "left"}, errors.InvalidAction),
        (RunStep, {"episode": 0, "seq": 1, "action": 1.0}, errors.InvalidAction),  # as action_id
        (RunStep, {"episode": 0, "seq": 1, "action": 4}, errors.InvalidAction),
        (RunStep, {"episode": -1, "seq": 1, "action": 1}, errors.MalformedMessage),
        (StartEpisode, {}, errors.MalformedMessage),
        (CreateRun, {"track": "3-on", "phase": "minival"}, errors.MalformedMessage),
        (CreateRun, {"track": "", "phase": "minival", "method": "m"}, errors.MalformedMessage),
        (CreateRun, {"track": "3-on", "phase": "p", "method": "m", "paper_url": "javascript:x"},
         errors.MalformedMessage),
        (CreateRun, {"track": "3-on", "phase": "p", "method": "m", "sensors": []}, errors.MalformedMessage),
    ],
)  # fmt: skip
def test_malformed_run_messages(cls: type, body: dict, error: type) -> None:
    with pytest.raises(error):
        cls.from_wire(body)


def test_the_run_client_is_light() -> None:
    """Participants need only the light client: no simulator, torch, web server or database."""
    import subprocess
    import sys

    check = (
        "import sys\n"
        "from multion_client.run import RunEnv\n"
        "from multion_client import RunEnv as Again\n"
        "assert RunEnv is Again\n"
        "heavy = {'pybullet', 'multion', 'torch', 'fastapi', 'sqlalchemy'} & set(sys.modules)\n"
        "assert not heavy, heavy\n"
    )
    subprocess.run([sys.executable, "-c", check], check=True, timeout=60)
