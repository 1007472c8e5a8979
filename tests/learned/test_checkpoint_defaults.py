"""Checkpoints made with the defaults before issue 31 (13-cell oracle crops with one cell per
goal, depth [0.5, 5] m, a 512-unit GRU) keep acting as trained; an environment that differs
from a checkpoint's is refused with the fields named."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from multion.config.codec import env_config_from_dict, env_config_to_dict
from multion_agents.agent import AgentError
from multion_agents.evaluate import EvalSettings, evaluate, resolve_config
from multion_agents.learned.agent import learned_agent_class
from multion_agents.learned.checkpoint import load_policy, save_checkpoint
from multion_agents.learned.models import build_policy, model_spec
from multion_agents.learned.policy import HIDDEN_SIZE
from multion_agents.learned.rollout_envs import training_env_config

SIZE = 36


def _old_config() -> dict[str, Any]:
    spec = model_spec("oracle-map")
    config = training_env_config(1, spec.train_sensors, SIZE, "train", None, 20)
    config["maps"] = {"ego_size": 13}
    config["camera"].update(min_depth=0.5, max_depth=5.0)
    config = env_config_to_dict(env_config_from_dict(config))
    del config["maps"]["goal_cells"]  # the field did not exist yet
    return config


def _old_checkpoint(path: Path) -> Path:
    config = _old_config()
    policy = build_policy(
        "oracle-map", {**config, "maps": {**config["maps"], "goal_cells": 1}}, 512
    )
    save_checkpoint(
        path, {"model": policy.state_dict(), "agent": "oracle-map", "env_config": config}
    )
    return path


def test_the_reference_gru_size_is_the_default() -> None:
    # saimwani/multiON habitat_baselines/config/multinav/ppo_multinav.yaml line 45
    assert HIDDEN_SIZE == 768
    config = training_env_config(1, model_spec("no-map").train_sensors, SIZE)
    assert build_policy("no-map", config).gru.hidden_size == 768


def test_an_old_checkpoint_loads_with_its_own_config(tmp_path: Path) -> None:
    policy, overrides, model = load_policy(_old_checkpoint(tmp_path / "old.pt"))
    assert model == "oracle-map" and policy.hidden_size == 512
    assert overrides["maps"]["ego_size"] == 13 and overrides["maps"]["goal_cells"] == 1
    assert (overrides["camera"]["min_depth"], overrides["camera"]["max_depth"]) == (0.5, 5.0)


def test_an_env_other_than_the_checkpoints_is_refused_naming_the_fields(tmp_path: Path) -> None:
    cls = learned_agent_class(_old_checkpoint(tmp_path / "old.pt"))
    agent = cls(seed=0)
    with pytest.raises(AgentError) as error:
        agent.configure(resolve_config({"camera": {"width": SIZE, "height": SIZE}}))
    for difference in (
        "maps.ego_size=50 (trained with 13)",
        "maps.goal_cells=3 (trained with 1)",
        "camera.min_depth=0.0 (trained with 0.5)",
        "camera.max_depth=10.0 (trained with 5.0)",
    ):
        assert difference in str(error.value)
    agent.configure(resolve_config(dict(cls.config_overrides)))


def test_an_old_checkpoint_is_evaluated_in_its_own_environment(
    tmp_path: Path, room_dataset: Path
) -> None:
    checkpoint = str(_old_checkpoint(tmp_path / "old.pt"))
    settings = EvalSettings(
        agent="oracle-map", num_goals=1, split="train", episodes=1, in_process=True,
        dataset=str(room_dataset), max_steps=5, checkpoint=checkpoint, deterministic=True,
    )  # fmt: skip
    result = evaluate(settings, progress=False)
    assert len(result.records) == 1
    maps, camera = result.resolved_config["maps"], result.resolved_config["camera"]
    assert (maps["ego_size"], maps["goal_cells"]) == (13, 1)
    assert (camera["min_depth"], camera["max_depth"]) == (0.5, 5.0)
    with pytest.raises(AgentError, match="camera.max_depth=10.0"):
        changed = EvalSettings(
            **{**settings.__dict__, "env_overrides": {"camera": {"max_depth": 10.0}}}
        )
        evaluate(changed, progress=False)
