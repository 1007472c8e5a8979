"""``multion bench --only learner``: the learner's cost per agent without a simulator."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from multion.config.codec import env_config_from_dict
from multion.task.spaces import build_observation_space
from multion_agents.bench.learner import learner_settings, run_learner_bench, synthetic_frames
from multion_agents.cli import main
from multion_agents.learned.models import model_spec
from multion_agents.learned.rollout_envs import training_env_config


@pytest.mark.parametrize("agent", ["obj-recog-map", "proj-neural-map", "oracle-map"])
def test_synthetic_frames_lie_in_the_observation_space(agent: str) -> None:
    sensors = model_spec(agent).train_sensors
    space = build_observation_space(
        env_config_from_dict(training_env_config(1, sensors, 36, "train"))
    )
    frames = synthetic_frames(space, sensors, steps=3, envs=2, seed=0)
    assert set(frames) == set(sensors)
    for key, tensor in frames.items():
        assert tensor.shape[:2] == (3, 2)
        for t in range(3):
            for e in range(2):
                value = tensor[t, e].numpy()
                assert space[key].contains(value if value.shape else np.int64(value)), key
    again = synthetic_frames(space, sensors, steps=3, envs=2, seed=0)
    assert all(torch.equal(frames[k], again[k]) for k in frames)  # seeded


def test_the_learner_bench_times_each_agent_and_compares_with_no_map(capsys) -> None:
    settings = learner_settings("no-map,obj-recog-map", 1, "cpu", envs="2,4")
    results = run_learner_bench(dataclasses.replace(settings, rollout_steps=4))
    assert results is not None and list(results) == ["no-map", "obj-recog-map"]
    for rows in results.values():
        assert list(rows) == [2, 4]  # one row per number of environments
        for figures in rows.values():
            assert figures["act_ms"] > 0 and figures["update_ms"] > 0
            total = figures["act_ms"] + figures["update_ms"]
            assert figures["fps"] == pytest.approx(1000 / total)
    out = capsys.readouterr().out
    assert "synthetic observations (no simulator)" in out
    rows = [line.split() for line in out.splitlines() if line.strip().startswith("obj-recog-map")]
    assert [row[1] for row in rows] == ["2", "4"] and all(row[-1].endswith("×") for row in rows)


def test_the_learner_bench_names_an_unknown_agent_and_a_bad_count(capsys) -> None:
    assert main(["bench", "--only", "learner", "--learner-agents", "no-map,nope"]) == 2
    err = capsys.readouterr().err
    assert "--learner-agents: unknown agent(s) nope" in err and "proj-neural-map" in err
    assert main(["bench", "--only", "learner", "--learner-updates", "0"]) == 2
    assert "--learner-updates 0: at least 1" in capsys.readouterr().err
    assert main(["bench", "--only", "learner", "--learner-envs", "8,0"]) == 2
    assert "--learner-envs '8,0': each count in 1-256" in capsys.readouterr().err
    assert main(["bench", "--only", "learner", "--learner-mixed-precision", "fp8"]) == 2
    assert "--learner-mixed-precision 'fp8': one of off, bf16, fp16" in capsys.readouterr().err
    assert main(["bench", "--only", "learner", "--learner-image-size", "512"]) == 2
    assert "--learner-image-size 512: in 36-128 pixels" in capsys.readouterr().err


def test_the_learner_bench_times_a_frozen_encoder_beside_the_learning_one(capsys) -> None:
    settings = learner_settings("no-map", 1, "cpu", envs="2", image_size=40, freeze_vision=True)
    results = run_learner_bench(dataclasses.replace(settings, rollout_steps=4))
    assert results is not None and list(results) == ["no-map", "no-map frozen"]
    assert results["no-map frozen"][2]["update_ms"] > 0
    out = capsys.readouterr().out
    assert "40² RGB-D" in out and "no-map: update with the encoder frozen, faster by 2 envs" in out


def test_the_learner_bench_times_a_bf16_update(capsys) -> None:
    settings = learner_settings("no-map", 1, "cpu", envs="2", mixed_precision="bf16")
    results = run_learner_bench(dataclasses.replace(settings, rollout_steps=4))
    assert results is not None and results["no-map"][2]["update_ms"] > 0
    assert "mixed precision bf16" in capsys.readouterr().out


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the message of a machine without one")
def test_the_cuda_learner_bench_says_plainly_it_needs_a_gpu(capsys) -> None:
    assert main(["bench", "--only", "learner", "--device", "cuda"]) == 2
    assert "needs a CUDA GPU" in capsys.readouterr().out
