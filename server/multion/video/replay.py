"""Playing a stored episode again, step by step, with a camera: what each video frame shows.

The simulator is deterministic, so the same episode, config and actions give the same frames;
a replay whose final metrics differ from the stored ones is refused (another dataset, secret or
simulator version would film something that never happened).
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from multion.config.episode import Episode
from multion.task.env import MultiONEnv
from multion.video.stored import VideoError


@dataclass(frozen=True)
class StepView:
    """What the camera and the task show after ``step`` actions (0: the start)."""

    step: int
    action: int | None
    """The action that led here; None at the start."""
    rgb: np.ndarray
    depth: np.ndarray
    position: np.ndarray
    yaw: float
    goals_found: int
    distance_to_goal: float
    """Geodesic distance to the current goal, metres (0 once every goal is found)."""
    found_correct: bool
    found_wrong: bool
    collided: bool
    metrics: dict[str, Any]


def replay(
    env: MultiONEnv,
    episode: Episode,
    actions: Sequence[int],
    stored_metrics: dict[str, Any],
    label: str,
) -> Iterator[StepView]:
    """The start and each step of ``actions`` played again in ``env``; a VideoError (naming
    the episode by ``label``) at the end when the replayed metrics are not ``stored_metrics``
    (:func:`replay_steps`)."""
    for observation, info, action in replay_steps(env, episode, actions, stored_metrics, label):
        yield _view(env, observation, info, action)


ReplayStep = tuple[dict[str, np.ndarray], dict[str, Any], int | None]
"""The observation and info after an action, and that action (None at the start)."""


def replay_steps(
    env: MultiONEnv,
    episode: Episode,
    actions: Sequence[int],
    stored_metrics: dict[str, Any],
    label: str,
) -> Iterator[ReplayStep]:
    """:func:`replay` without a camera: what ``env`` observes and reports at the start and
    after each of ``actions``; a VideoError when the episode ends before its last action, and
    at the end when the replayed metrics are not ``stored_metrics``.

    Only the metrics that ``stored_metrics`` has are compared: an episode that a leaderboard
    ended by a timeout keeps its own end reason, which a replay cannot reproduce, and a measure
    added to the task after the run was stored is no difference."""
    observation, info = env.reset(options={"episode": episode})
    yield observation, info, None
    done = False
    for step, action in enumerate(actions, start=1):
        if done:
            raise VideoError(
                f"episode {label}: the replay ended after {step - 1} of "
                f"{len(actions)} recorded actions"
            )
        observation, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        yield observation, info, action
    replayed = json.loads(json.dumps(info["metrics"]))  # compared as stored (JSON)
    differences = [
        f"{key} {replayed.get(key)!r} (recorded {value!r})"
        for key, value in stored_metrics.items()
        if replayed.get(key) != value
    ]
    if differences:
        raise VideoError(
            f"episode {label}: the replay does not reproduce the recorded metrics: "
            f"{'; '.join(differences[:4])} (another dataset or simulator version?)"
        )


def _view(
    env: MultiONEnv, observation: dict[str, np.ndarray], info: dict[str, Any], action: int | None
) -> StepView:
    state = env.state
    assert state is not None
    return StepView(
        step=state.step,
        action=action,
        rgb=observation["rgb"],
        depth=observation["depth"],
        position=env.sim.position.copy(),
        yaw=float(env.sim.yaw),
        goals_found=state.goals_found,
        distance_to_goal=float(state.distance_to_goal),
        found_correct=state.found_correct,
        found_wrong=state.found_wrong,
        collided=state.collided,
        metrics=info["metrics"],
    )
