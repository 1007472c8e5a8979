"""The imitation labels (``learned/expert.py``) and the PPO loss that uses them."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from rollouts import SIZE, random_rollout, room_env, space_for

from multion.config.codec import env_config_from_dict, env_config_to_dict
from multion.task.env import MultiONEnv
from multion_agents.baselines.explorer import ExplorerAgent
from multion_agents.learned.checkpoint import CheckpointError, load_checkpoint
from multion_agents.learned.env_groups import EnvGroups
from multion_agents.learned.expert import (
    EXPERT_ACTION,
    EXPERT_LABELS,
    EXPERT_SENSORS,
    ExpertLabels,
    ExplorerLabels,
    OraclePlannerLabels,
)
from multion_agents.learned.found_gate import FOUND
from multion_agents.learned.models import MODELS
from multion_agents.learned.ppo import Args, ppo_loss
from multion_agents.learned.rollout import collect, start_episodes
from multion_agents.learned.rollout_envs import NO_LABEL, expert_labels
from multion_agents.learned.train_options import EXPERTS
from multion_agents.learned.training_run import train
from multion_client.constants import Action


def _room_env(dataset: Path, sensors: tuple[str, ...] = ("rgb", *EXPERT_SENSORS)) -> MultiONEnv:
    return room_env(dataset, sensors)


def _follow_labels(env: ExpertLabels, info: dict, steps: int) -> tuple[list[int], dict]:
    """Take the labelled action until the episode ends (at most ``steps``): the actions taken
    and the last info."""
    taken: list[int] = []
    for _ in range(steps):
        taken.append(info[EXPERT_ACTION])
        _, _, terminated, truncated, info = env.step(taken[-1])
        if terminated or truncated:
            break
    return taken, info


def test_following_the_labels_finds_every_goal(room_dataset: Path) -> None:
    env = OraclePlannerLabels(_room_env(room_dataset))
    for index in range(4):
        _, info = env.reset(options={"episode_index": index})
        _, info = _follow_labels(env, info, 200)
        assert env.unwrapped.metrics()["success"] == 1.0
        assert EXPERT_ACTION not in info  # no label for the observation that ends the episode


def test_labels_follow_the_learners_own_steps(room_dataset: Path) -> None:
    """The learner turns where the expert would step: the expert is told what was done, so it
    does not take a turn for a refused step (which would make it re-plan), and it still leads
    to the goal from wherever the learner went."""
    env = OraclePlannerLabels(_room_env(room_dataset))
    _, info = env.reset(options={"episode_index": 0})
    for _ in range(12):  # a full circle of 30° turns
        _, _, terminated, _, info = env.step(int(Action.TURN_LEFT))
        assert not terminated
    assert env.planner.replans == 0
    _follow_labels(env, info, 200)
    assert env.unwrapped.metrics()["success"] == 1.0


def test_the_expert_needs_its_sensors(room_dataset: Path) -> None:
    with pytest.raises(ValueError, match=r"the expert needs sensors \['gps', 'compass'\]"):
        OraclePlannerLabels(_room_env(room_dataset, sensors=("rgb", "goal")))


def test_vector_infos_become_labels_with_gaps() -> None:
    infos = {EXPERT_ACTION: np.array([2, 0, 3]), f"_{EXPERT_ACTION}": np.array([True, False, True])}
    assert expert_labels(infos, 3).tolist() == [2, NO_LABEL, 3]
    assert expert_labels({}, 2).tolist() == [NO_LABEL, NO_LABEL]


def _oracle_map_config() -> dict[str, object]:
    """The env config of ``space_for("oracle-map")``, for ``build_policy``."""
    return {
        "sensors": list(MODELS["oracle-map"].train_sensors),
        "camera": {"width": SIZE, "height": SIZE},
    }


class _CountingEnvs:
    """A stand-in vector env whose ``goal`` observation counts the steps of each env, whose
    label for an observation is that count mod 4, and whose episodes last 3 steps."""

    num_envs = 2

    def __init__(self, space) -> None:
        self.space, self.count = space, np.zeros(2, dtype=np.int64)

    def _observe(self) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        frames = {k: np.stack([self.space[k].sample() for _ in range(2)]) for k in self.space}
        frames["goal"] = self.count % 8
        labels = {EXPERT_ACTION: self.count % 4, f"_{EXPERT_ACTION}": np.ones(2, dtype=bool)}
        return frames, labels

    def reset(self, seed: int | None = None):
        self.count[:] = 0
        return self._observe()

    def step(self, actions: np.ndarray):
        self.count += 1
        done = self.count % 3 == 0
        frames, infos = self._observe()
        return frames, np.zeros(2), done, np.zeros(2, dtype=bool), infos


def test_a_rollout_stores_each_label_with_the_frame_it_labels() -> None:
    from collections import deque

    from multion_agents.learned.models import build_policy

    space = space_for("oracle-map")
    space.seed(0)
    policy = build_policy("oracle-map", _oracle_map_config())
    envs = EnvGroups([_CountingEnvs(space)])  # type: ignore[list-item]
    live = start_episodes(envs, policy, seed=0)
    rollout, _, _ = collect(envs, policy, live, 7, deque())
    assert rollout.expert_actions.shape == (7, 2)
    assert torch.equal(rollout.expert_actions, rollout.frames["goal"] % 4)
    assert rollout.expert_actions[:, 0].tolist() == [0, 1, 2, 3, 0, 1, 2]


def test_the_imitation_loss_is_the_cross_entropy_of_the_labelled_steps() -> None:
    from multion_agents.learned.models import build_policy

    torch.manual_seed(0)
    policy = build_policy("oracle-map", _oracle_map_config())
    rollout = random_rollout(space_for("oracle-map"), seed=3)
    rollout.initial_state = policy.initial_state(2)
    labels = torch.randint(0, 4, rollout.actions.shape, generator=torch.Generator().manual_seed(1))
    labels[0, 0] = labels[2, 1] = NO_LABEL
    rollout.expert_actions = labels
    plain, _ = ppo_loss(policy, rollout, 0.2, Args())
    mixed, terms = ppo_loss(policy, rollout, 0.2, Args(imitation_coef=2.0))
    out = policy(rollout.frames, rollout.prev_actions, rollout.starts, rollout.initial_state)
    keep = labels != NO_LABEL
    expected = torch.nn.functional.cross_entropy(out.logits[keep], labels[keep])
    assert terms["imitation_loss"] is not None
    assert float(terms["imitation_loss"]) == pytest.approx(float(expected), rel=1e-5)
    assert float(mixed - plain) == pytest.approx(2.0 * float(expected), rel=1e-4)
    rollout.expert_actions = torch.full_like(labels, NO_LABEL)
    unlabelled, terms = ppo_loss(policy, rollout, 0.2, Args(imitation_coef=2.0))
    assert terms["imitation_loss"] is None and float(unlabelled) == pytest.approx(float(plain))


def test_with_a_found_head_imitation_teaches_the_movements_where_the_actor_moved() -> None:
    """The head decides FOUND and the replay gates the actor's logits: a FOUND label, or a step
    where the gate fired (FOUND taken), would be a cross-entropy against an impossible action.
    The loss is the movement labels' cross-entropy on the steps the actor chose, and finite."""
    from multion_agents.learned.models import build_policy

    torch.manual_seed(0)
    policy = build_policy("oracle-map", _oracle_map_config(), found_head=True)
    rollout = random_rollout(space_for("oracle-map"), seed=3)
    rollout.initial_state = policy.initial_state(2)
    labels = torch.randint(0, 4, rollout.actions.shape, generator=torch.Generator().manual_seed(1))
    labels[0, 0] = NO_LABEL
    labels[1, 0] = FOUND
    rollout.actions[2, 1] = FOUND  # the gate fired there
    labels[2, 1] = int(Action.TURN_LEFT)
    rollout.expert_actions = labels
    _, terms = ppo_loss(policy, rollout, 0.2, Args(imitation_coef=1.0, found_head=1.0))
    fired = rollout.actions == FOUND
    out = policy(rollout.frames, rollout.prev_actions, rollout.starts, rollout.initial_state, fired)
    keep = (labels != NO_LABEL) & (labels != FOUND) & ~fired
    assert 0 < int(keep.sum()) < labels.numel() - 2
    expected = torch.nn.functional.cross_entropy(out.logits[keep], labels[keep])
    assert terms["imitation_loss"] is not None and math.isfinite(float(terms["imitation_loss"]))
    assert float(terms["imitation_loss"]) == pytest.approx(float(expected), rel=1e-5)


@pytest.mark.parametrize(
    ("agent", "expert", "found_head"),
    [
        ("oracle-map", "oracle-planner", 0.0),
        ("no-map", "explorer", 0.0),
        ("no-map", "explorer", 1.0),
    ],
)
def test_training_with_imitation_logs_its_loss_and_agreement(
    tmp_path: Path, room_dataset: Path, agent: str, expert: str, found_head: float
) -> None:
    args = Args(
        agent=agent, task="1-on", frames=128, envs=2, rollout_steps=32, image_size=36,
        dataset=str(room_dataset), max_steps=40, out=str(tmp_path / "run"), progress=False,
        tensorboard=False, imitation_coef=1.0, expert=expert, found_head=found_head,
    )  # fmt: skip
    train(args)
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert len(rows) == 2
    for row in rows:
        assert math.isfinite(float(row["imitation_loss"])) and float(row["imitation_loss"]) > 0
        assert 0.0 <= float(row["expert_agreement"]) <= 1.0
    assert load_checkpoint(tmp_path / "run" / "checkpoint.pt")["args"]["expert"] == expert
    other = "oracle-planner" if expert == "explorer" else "explorer"
    resumed = dataclasses.replace(args, frames=192, resume=True, expert=other)
    with pytest.raises(
        CheckpointError, match=f"--expert '{expert}' \\(this run asks for '{other}'\\)"
    ):
        train(resumed)


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--imitation-coef", "-1"], "--imitation-coef must be in \\[0, 100\\], got -1.0"),
        (["--imitation-coef", "101"], "--imitation-coef must be in \\[0, 100\\], got 101.0"),
        (
            ["--imitation-coef", "1", "--server", "http://127.0.0.1:9"],
            "needs local environments, not --server",
        ),
        (["--expert", "explorer"], "--expert explorer labels .* needs --imitation-coef above 0"),
        (["--imitation-coef", "1", "--expert", "human"], "--expert"),
    ],
)
def test_train_cli_rejects_bad_imitation(tmp_path: Path, capsys, flags, message) -> None:
    import re

    from multion_agents.cli import main

    code = main(["train", *flags, "--frames", "64", "--out", str(tmp_path)])
    assert code == 2
    assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "checkpoint.pt").exists()


def test_labels_are_never_lattice_search_moves(room_dataset: Path) -> None:
    """Turning on the spot returns to one position every step; the planner's own loop breaker
    would start a search there and label its moves."""
    env = OraclePlannerLabels(_room_env(room_dataset))
    env.reset(options={"episode_index": 1})
    for _ in range(24):
        env.step(int(Action.TURN_RIGHT))
    assert env.planner.searches == 0


def _explorer_env(dataset: Path, size: int = 64) -> MultiONEnv:
    """The room with what the explorer reads (at 36², it misses the goal in 2 of these 4)."""
    config = {
        "task": {"num_goals": 1},
        "camera": {"width": size, "height": size},
        "sensors": list(ExplorerAgent.sensors),
        "dataset": str(dataset),
        "split": "train",
    }
    return MultiONEnv(env_config_from_dict(config))


def test_a_learner_that_follows_the_explorers_labels_plays_the_explorers_episode(
    room_dataset: Path,
) -> None:
    """DAgger with the learner doing what the label says is the explorer playing alone: same
    actions, step for step, and it finds the goal."""
    for index in range(2):
        env = _explorer_env(room_dataset)
        alone = ExplorerAgent()
        alone.configure(env_config_to_dict(env.config))
        alone.reset()
        observation, _ = env.reset(options={"episode_index": index})
        own: list[int] = []
        for _ in range(400):
            own.append(alone.act(observation))
            observation, _, terminated, truncated, _ = env.step(own[-1])
            if terminated or truncated:
                break
        assert env.metrics()["success"] == 1.0

        labelled = ExplorerLabels(_explorer_env(room_dataset))
        _, info = labelled.reset(options={"episode_index": index})
        followed, _ = _follow_labels(labelled, info, 400)
        assert followed == own
        assert labelled.unwrapped.metrics()["success"] == 1.0


def test_the_explorer_learns_from_the_learners_steps_not_its_own_labels(
    room_dataset: Path,
) -> None:
    """The learner turns where the explorer said "forward": told so, the explorer does not take
    the unchanged position for a refused step and wall off the free floor ahead; and it still
    leads to the goal from wherever the learner turned."""
    env = ExplorerLabels(_explorer_env(room_dataset))
    _, info = env.reset(options={"episode_index": 0})
    forward_labels = 0
    for _ in range(12):  # a full circle of 30° turns, whatever the labels say
        forward_labels += info[EXPERT_ACTION] == Action.MOVE_FORWARD
        _, _, terminated, _, info = env.step(int(Action.TURN_LEFT))
        assert not terminated
    assert forward_labels > 0
    assert not env.explorer._blocked.any()  # noqa: SLF001 (what "refused" would have marked)
    _follow_labels(env, info, 400)
    assert env.unwrapped.metrics()["success"] == 1.0


def test_every_expert_the_cli_offers_has_labels() -> None:
    assert tuple(EXPERT_LABELS) == EXPERTS  # train_options stays light; the registry here


def test_the_explorer_needs_its_sensors(room_dataset: Path) -> None:
    with pytest.raises(ValueError, match=r"the explorer needs sensors \['depth'\]"):
        ExplorerLabels(_room_env(room_dataset, sensors=("rgb", *EXPERT_SENSORS)))
