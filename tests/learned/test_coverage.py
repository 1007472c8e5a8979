"""``--coverage-reward`` (``learned/coverage.py``): the exploration bonus on the task's reward."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from rollouts import room_env
from test_recipe_options import tiny_args

from multion.config.ranges import ConfigError
from multion_agents.learned.checkpoint import CheckpointError, load_checkpoint
from multion_agents.learned.coverage import CoverageBonus, coverage_bonus, visit_cell
from multion_agents.learned.rollout_envs import TrainingWrappers, make_vector_env
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_run import train
from multion_client.constants import Action


def test_the_bonus_decays_with_the_step_and_the_visits() -> None:
    assert coverage_bonus(0.25, 1, 1) == pytest.approx(0.25 * 0.995)
    assert coverage_bonus(0.25, 200, 1) == pytest.approx(0.25 * 0.995**200)
    assert coverage_bonus(0.25, 10, 4) == pytest.approx(0.25 * 0.995**10 / 4)


@pytest.mark.parametrize(
    ("gps", "cell"),
    [((0.0, 0.0), (0, 0)), ((1.24, -1.24), (0, 0)), ((1.26, 0.0), (1, 0)),
     ((-1.26, 3.8), (-1, 2)), ((0.0, -1.26), (0, -1))],
)  # fmt: skip
def test_cells_are_2_5_m_with_the_start_at_a_centre(
    gps: tuple[float, float], cell: tuple[int, int]
) -> None:
    assert visit_cell(np.array(gps)) == cell


def test_the_wrapper_adds_the_bonus_of_the_cell_the_step_ends_in(room_dataset: Path) -> None:
    """The same episode and actions with and without the wrapper: the rewards differ by the
    bonus computed by hand from the unwrapped env's own gps readings."""
    actions = (
        [int(Action.MOVE_FORWARD)] * 14
        + [int(Action.TURN_LEFT)] * 3
        + [int(Action.MOVE_FORWARD)] * 4
    )
    plain = room_env(room_dataset, ("rgb", "gps"))
    wrapped = CoverageBonus(room_env(room_dataset, ("rgb", "gps")), 0.25)
    observation, _ = plain.reset(options={"episode_index": 0})
    wrapped.reset(options={"episode_index": 0})
    visits = {visit_cell(observation["gps"]): 1}
    cells_entered = set(visits)
    for step, action in enumerate(actions, start=1):
        observation, reward, done, cut, _ = plain.step(action)
        _, bonus_reward, wrapped_done, wrapped_cut, _ = wrapped.step(action)
        cell = visit_cell(observation["gps"])
        visits[cell] = visits.get(cell, 0) + 1
        cells_entered.add(cell)
        expected = 0.25 * 0.995**step / visits[cell]
        assert float(bonus_reward) - float(reward) == pytest.approx(expected, abs=1e-9)
        assert (wrapped_done, wrapped_cut) == (done, cut)
        if done or cut:
            break
    assert len(cells_entered) >= 2  # the walk left the start cell: new ground paid again in full


def test_the_wrapper_needs_gps_and_a_positive_reward(room_dataset: Path) -> None:
    with pytest.raises(ValueError, match="needs sensors"):
        CoverageBonus(room_env(room_dataset, ("rgb",)), 0.25)
    with pytest.raises(ValueError, match="above 0"):
        CoverageBonus(room_env(room_dataset, ("rgb", "gps")), 0.0)


def test_the_option_is_bounded_and_local_only() -> None:
    with pytest.raises(ValueError, match=r"--coverage-reward must be in \[0, 10\]"):
        Args(coverage_reward=11.0)
    with pytest.raises(
        ConfigError, match="--coverage-reward work beside the simulator: each needs local"
    ):
        make_vector_env({}, 2, servers=("http://127.0.0.1:9",),
                        wrappers=TrainingWrappers(coverage_reward=0.25))  # fmt: skip


def test_a_run_with_the_bonus_refuses_to_resume_without_it(
    tmp_path: Path, room_dataset: Path
) -> None:
    args = tiny_args(tmp_path, room_dataset, frames=128)
    train(dataclasses.replace(args, coverage_reward=0.25))
    recorded = load_checkpoint(tmp_path / "run" / "checkpoint.pt")["args"]
    assert recorded["coverage_reward"] == 0.25
    with pytest.raises(CheckpointError, match="--coverage-reward 0.25"):
        train(dataclasses.replace(args, frames=256, resume=True))
