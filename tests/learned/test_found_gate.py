"""The FOUND head's gate (issue 51): lower gates read off episodes played at one gate, checked
against hand-made traces and against episodes actually played with those gates; the gate an
evaluation sets, refused for a policy without a head and recorded in metrics.json."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from rollouts import SIZE
from test_recipe_options import tiny_args

from multion_agents.agent import AgentError
from multion_agents.learned.agent import learned_agent_class
from multion_agents.learned.diagnose import diagnosis_config, found_calls
from multion_agents.learned.found_gate import FOUND_GATE, GateTrace, ending_at_gate, parse_gates
from multion_agents.learned.models import model_spec
from multion_agents.learned.policy import RecurrentPolicy
from multion_agents.learned.training_run import train
from multion_client.constants import Action

FOUND = int(Action.FOUND)


def _trace(probability: list[float], in_reach: list[bool], ending: str) -> GateTrace:
    return GateTrace(np.array(probability), np.array(in_reach), np.array(in_reach), ending)


def test_a_lower_gate_ends_the_episode_at_the_first_step_above_it() -> None:
    trace = _trace([0.1, 0.3, 0.2, 0.6], [False, True, False, True], "success")
    assert ending_at_gate(trace, 0.5) == "success"  # as played: the FOUND at step 3
    assert ending_at_gate(trace, 0.4) == "success"  # step 3 still the first above 0.4
    assert ending_at_gate(trace, 0.25) == "success"  # step 1, within reach
    assert ending_at_gate(trace, 0.05) == "wrong_found"  # step 0, out of reach
    assert ending_at_gate(trace, 0.3) == "success"  # 0.3 does not exceed 0.3: step 3
    wandered = _trace([0.1, 0.45, 0.2], [False, False, True], "max_steps")
    assert ending_at_gate(wandered, 0.5) == "max_steps"
    assert ending_at_gate(wandered, 0.15) == "wrong_found"
    assert ending_at_gate(wandered, 0.46) == "max_steps"


@pytest.mark.parametrize("gate", [0.0, 0.6, -0.1])
def test_a_gate_above_the_one_played_cannot_be_read(gate: float) -> None:
    with pytest.raises(ValueError, match=r"a gate must be in \(0, 0.5\]"):
        ending_at_gate(_trace([0.1], [False], "max_steps"), gate)


def test_gates_parse_sorted_and_bounded() -> None:
    assert parse_gates("0.3, 0.1,0.3") == (0.1, 0.3)
    for text in ("0.7", "0", "", "a,b"):
        with pytest.raises(ValueError, match="--gates"):
            parse_gates(text)


def _spread_head(policy: RecurrentPolicy) -> None:
    """A head whose probability wanders between about 0.05 and 0.6 from step to step."""
    assert policy.found_head is not None
    with torch.no_grad():
        policy.found_head.weight.mul_(40.0)
        policy.found_head.bias.fill_(-1.2)


def test_the_gate_sets_where_the_policy_calls_found() -> None:
    torch.manual_seed(0)
    from rollouts import sample_frames, space_for

    space = space_for("no-map")
    policy = model_spec("no-map").build(space, found_head=True)
    assert policy.found_gate == FOUND_GATE
    frames = {k: v for k, v in sample_frames(space, 1, 4).items() if k in policy.sensors}
    assert policy.found_head is not None
    with torch.no_grad():
        policy.found_head.bias.fill_(-0.85)  # probability about 0.3
        out = policy(frames, torch.zeros(1, 4, dtype=torch.long), torch.ones(1, 4),
                     policy.initial_state(4))  # fmt: skip
        assert float(torch.softmax(out.logits, -1)[..., FOUND].max()) == 0.0
        policy.found_gate = 0.2
        out = policy(frames, torch.zeros(1, 4, dtype=torch.long), torch.ones(1, 4),
                     policy.initial_state(4))  # fmt: skip
    assert float(torch.softmax(out.logits, -1)[..., FOUND].min()) == 1.0


def test_gates_read_off_played_episodes_match_episodes_played_with_them() -> None:
    """The claim of ``found_gate``: replaying nothing, the endings read for a lower gate are
    those of the same episodes (same seed) played with that gate."""
    torch.manual_seed(1)
    config = diagnosis_config({"camera": {"width": SIZE, "height": SIZE}}, ("rgb", "depth", "goal"))
    config = dataclasses.replace(config, task=dataclasses.replace(config.task, max_steps=60))
    from multion.task.spaces import build_observation_space

    policy = model_spec("no-map").build(build_observation_space(config), found_head=True)
    _spread_head(policy)
    gates = (0.1, 0.2, 0.3, 0.4, 0.5)
    played = found_calls(policy, config, episodes=6, seed=3, gates=gates)
    assert played.gate_endings["0.5"] == played.endings
    assert played.endings.get("success", 0) <= played.reached <= 6
    assert played.seen_in_reach <= played.reached
    assert played.seen_in_reach <= played.saw_goal <= 6  # in view within reach: in view
    assert played.in_view_steps + played.seen_out_of_view_steps <= played.near_steps
    won = played.endings.get("success", 0)
    assert played.missed_in_reach == played.reached - won  # 1-ON: a win came within reach
    # 60 steps of 0.25 m cross at most 15 m * sqrt(2) / 2.5 m cell borders
    assert 1 <= played.cells_visited <= 1 + 15 * math.sqrt(2) / 2.5
    read = {gate: played.gate_endings[f"{gate:g}"] for gate in gates}
    assert len({tuple(sorted(r.items())) for r in read.values()}) > 1, read  # gates matter here
    for gate in (0.1, 0.3):
        policy.found_gate = gate
        assert found_calls(policy, config, episodes=6, seed=3).endings == read[gate], gate


def test_an_evaluation_sets_the_gate_and_a_policy_without_a_head_refuses_it(
    tmp_path: Path, room_dataset: Path
) -> None:
    train(tiny_args(tmp_path / "head", room_dataset, found_head=1.0, frames=128))
    checkpoint = tmp_path / "head" / "run" / "checkpoint.pt"
    cls = learned_agent_class(checkpoint, found_gate=0.2)
    assert cls.policy is not None and cls.policy.found_gate == 0.2
    assert cls(seed=0).recorded_settings() == {"found_gate": 0.2}
    assert learned_agent_class(checkpoint)(seed=0).recorded_settings() == {"found_gate": 0.5}
    train(tiny_args(tmp_path / "plain", room_dataset, frames=128))
    plain = tmp_path / "plain" / "run" / "checkpoint.pt"
    with pytest.raises(AgentError, match="--found-gate 0.2: .* has no FOUND head"):
        learned_agent_class(plain, found_gate=0.2)
    assert learned_agent_class(plain)(seed=0).recorded_settings() == {}


def test_eval_records_the_gate_and_names_a_bad_one(
    tmp_path: Path, room_dataset: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from multion_agents.cli import main

    train(tiny_args(tmp_path, room_dataset, found_head=1.0, frames=128))
    checkpoint = str(tmp_path / "run" / "checkpoint.pt")
    common = ["eval", "--agent", "no-map", "--checkpoint", checkpoint, "--task", "1-on",
              "--dataset", str(room_dataset), "--episodes", "1", "--in-process",
              "--max-steps", "20", "--quiet"]  # fmt: skip
    assert main([*common, "--found-gate", "0.3", "--out", str(tmp_path / "e")]) == 0
    run = json.loads((tmp_path / "e" / "metrics.json").read_text())["run"]
    assert run["agent_settings"] == {"found_gate": 0.3}
    assert main([*common, "--found-gate", "1.5"]) == 2
    assert "--found-gate must be" in capsys.readouterr().err


def _probe_script():
    path = Path(__file__).resolve().parents[2] / "scripts" / "found_head_probe.py"
    spec = importlib.util.spec_from_file_location("found_head_probe", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module, path


def test_the_probe_scripts_auc_is_the_share_of_pairs_ranked_right() -> None:
    module, _ = _probe_script()
    labels = np.array([False, True, False, True, False])
    assert module.auc(np.array([0.1, 0.9, 0.2, 0.8, 0.3]), labels) == 1.0
    assert module.auc(np.array([0.9, 0.1, 0.8, 0.2, 0.7]), labels) == 0.0
    assert module.auc(np.array([0.1, 0.5, 0.6, 0.9, 0.2]), labels) == pytest.approx(5 / 6)
    assert np.isnan(module.auc(np.array([0.1, 0.2]), np.array([False, False])))


def test_the_probe_script_scores_head_and_probe_of_a_checkpoint(
    tmp_path: Path, room_dataset: Path
) -> None:
    _, script = _probe_script()
    train(tiny_args(tmp_path, room_dataset, found_head=1.0, frames=128))
    checkpoint = str(tmp_path / "run" / "checkpoint.pt")
    done = subprocess.run(
        [sys.executable, str(script), checkpoint, "--episodes", "1", "--max-steps", "20"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "the trained head" in done.stdout and "a balanced probe of its input" in done.stdout
    assert "20 train-house steps" in done.stdout and "20 val-house steps" in done.stdout
    plain = tmp_path / "plain"
    train(tiny_args(plain, room_dataset, frames=128))
    refused = subprocess.run(
        [sys.executable, str(script), str(plain / "run" / "checkpoint.pt")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert refused.returncode == 2 and "has no FOUND head" in refused.stderr
