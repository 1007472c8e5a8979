"""What a trained checkpoint sees and does (``multion diagnose``; issue 51 item 1).

Three measurements, each aimed at one reason an agent that must see its goal may not learn:

* **seeing**: does the image encoder tell when the episode's goal shows? A linear probe (the
  head of :mod:`.vision_pretrain`) is trained on the checkpoint's frozen image embedding with
  frames of train houses, then scored on frames of val houses: recall and precision of "the
  goal shows", by distance band. ObjRecogMap's own recogniser is scored on the same frames.
* **calling FOUND**: the policy's probability of FOUND at steps within the success distance of
  the goal against steps farther away, on val episodes it plays (sampled actions).
* **endings**: how those episodes end (success, wrong FOUND, step limit), and for a FOUND
  head, how they would have ended with its gate lower (:mod:`.found_gate`).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from multion.config.codec import env_config_from_dict
from multion.config.task import EnvConfig
from multion.task.env import MultiONEnv
from multion_agents.agent import ConfigOverrides, merge_overrides
from multion_agents.learned.found_gate import GateTrace, gate_endings
from multion_agents.learned.found_supervision import (
    FOUND_LABEL_SENSOR,
    IN_VIEW_SENSOR,
    found_probabilities,
)
from multion_agents.learned.goal_heads import GOAL_VECTOR, goal_seen
from multion_agents.learned.learned_maps import ObjRecogMap
from multion_agents.learned.policy import PolicyOutput, RecurrentPolicy, frames_to_tensors
from multion_agents.learned.train_options import VisionPretraining
from multion_agents.learned.vision_frames import VisionFrames, goal_in_view, sample_frames
from multion_agents.learned.vision_pretrain import (
    BandScores,
    PlaceHead,
    band_scores,
    fit_head,
    predict_goal_in_view,
    recogniser_answers,
)


@dataclass(frozen=True)
class FoundCalls:
    """FOUND's probability on the steps of played episodes, near the goal and farther."""

    near_steps: int
    near_probability: float
    """Mean probability of FOUND where the goal is within the success distance (nan: none)."""
    far_steps: int
    far_probability: float
    endings: dict[str, int] = field(default_factory=dict)
    """Episodes by how they ended (``end_reason``)."""
    reached: int = 0
    """Episodes that came within the success distance of the goal at least once: those a FOUND
    called at the right step would have won (``random-oracle-found``'s way of calling it)."""
    seen_in_reach: int = 0
    """Episodes with a step within reach where the frame shows the goal (``goal_mask``): those
    a FOUND head's label says FOUND in."""
    in_view_steps: int = 0
    """Steps within reach where the frame shows the goal."""
    in_view_probability: float = math.nan
    """Mean probability of FOUND on those steps (nan: none)."""
    missed_in_reach: int = 0
    """Episodes that came within reach and were not won."""
    seen_out_of_view_steps: int = 0
    """Steps within reach where the frame does not show the goal but it has been in view this
    episode (``goal_vector``'s flag): a goal underfoot, or one turned away from. The FOUND head
    learns "not here" on them with ``--found-head-label in-view`` and "here" with ``seen``."""
    seen_out_of_view_probability: float = math.nan
    """Mean probability of FOUND on those steps (nan: none)."""
    saw_goal: int = 0
    """Episodes whose goal came into view (the task's ``current_goal_seen``: in the field of
    view within ``maps.view_distance``, a clear line on the grid): those the search served."""
    cells_visited: float = math.nan
    """Mean per episode of the task's ``cells_visited`` (the 2.5 m cells of the start frame it
    entered): how much ground it searched."""
    cells_at_step_limit: float = math.nan
    """The same mean over the episodes that reached the step limit (nan: none did)."""
    gate_endings: dict[str, dict[str, int]] = field(default_factory=dict)
    """With a FOUND head: per gate (a probability, as text), the episodes by how they would
    have ended with it (:func:`.found_gate.gate_endings`)."""


def diagnosis_config(
    overrides: ConfigOverrides, sensors: tuple[str, ...], split: str = "val"
) -> EnvConfig:
    """A 1-ON env config of ``split`` with the checkpoint's camera and maps (``overrides``)."""
    base: dict[str, Any] = {"task": {"num_goals": 1}, "split": split, "sensors": list(sensors)}
    return env_config_from_dict(merge_overrides(base, overrides))


StepHook = Callable[[int, dict[str, Any], PolicyOutput], None]
"""Called at each step of :func:`play`, before acting: (episode, observation, policy output)."""


def play(
    policy: RecurrentPolicy,
    config: EnvConfig,
    episodes: int,
    seed: int,
    on_step: StepHook,
    progress: bool = False,
) -> list[dict[str, Any]]:
    """Play ``episodes`` episodes of ``config`` with ``policy`` (actions sampled with ``seed``):
    of a dataset, evenly spaced ones, those ``multion eval --episodes`` plays. Calls ``on_step``
    at every step; returns each episode's final metrics (``end_reason``, ``cells_visited``, …)."""
    rng = np.random.default_rng(seed)
    finals: list[dict[str, Any]] = []
    env = MultiONEnv(config)
    device = policy.device
    policy.eval()
    try:
        for index in tqdm(range(episodes), desc="episodes", disable=not progress):
            listed = env.episodes  # None: sampled online (train houses)
            options = {} if listed is None else {"episode_index": index * len(listed) // episodes}
            observation, _ = env.reset(seed=index, options=options)
            state, previous, start, done = policy.initial_state(1), 0, True, False
            info: dict[str, Any] = {}
            while not done:
                frame = frames_to_tensors(observation, policy.sensors)
                with torch.no_grad():
                    out = policy.step(
                        {k: v.unsqueeze(0).to(device) for k, v in frame.items()},
                        torch.tensor([previous], device=device),
                        torch.tensor([float(start)], device=device),
                        state,
                    )
                state, start = out.state, False
                on_step(index, observation, out)
                probabilities = torch.softmax(out.logits[0, 0].double(), 0).cpu().numpy()
                previous = int(
                    rng.choice(len(probabilities), p=probabilities / probabilities.sum())
                )
                observation, _, terminated, truncated, info = env.step(previous)
                done = terminated or truncated
            finals.append(dict(info["metrics"]))
    finally:
        env.close()
    return finals


def shows_goal(observation: dict[str, Any]) -> bool:
    """Whether the frame shows the current goal: a ``goal_mask`` pixel holds its category + 1."""
    goal = int(np.asarray(observation["goal"]).reshape(-1)[0])
    return bool(np.any(np.asarray(observation[IN_VIEW_SENSOR]) == goal + 1))


def found_calls(
    policy: RecurrentPolicy,
    config: EnvConfig,
    episodes: int,
    seed: int,
    progress: bool = False,
    gates: Sequence[float] = (),
) -> FoundCalls:
    """Play ``episodes`` episodes of ``config`` with ``policy`` (:func:`play`), recording
    FOUND's probability at every step (a FOUND head's own), where the goal is within reach and
    in view, and with a FOUND head, how the episodes would have ended with each of ``gates``."""
    oracles = (FOUND_LABEL_SENSOR, IN_VIEW_SENSOR, GOAL_VECTOR)
    config = replace(config, sensors=tuple(dict.fromkeys((*config.sensors, *oracles))))
    reach = config.task.success_distance
    chances: list[list[float]] = [[] for _ in range(episodes)]
    in_reach: list[list[bool]] = [[] for _ in range(episodes)]
    in_view: list[list[bool]] = [[] for _ in range(episodes)]
    seen: list[list[bool]] = [[] for _ in range(episodes)]

    def record(episode: int, observation: dict[str, Any], out: PolicyOutput) -> None:
        # with --found-head, the head's probability (its gate opens above found_gate)
        head = None if out.found_logit is None else out.found_logit[0, 0]
        chances[episode].append(float(found_probabilities(out.logits[0, 0], head)[0]))
        in_reach[episode].append(float(observation[FOUND_LABEL_SENSOR][0]) <= reach)
        in_view[episode].append(shows_goal(observation))
        seen[episode].append(bool(goal_seen(torch.as_tensor(observation[GOAL_VECTOR]))))

    finals = play(policy, config, episodes, seed, record, progress)
    endings = [str(final["end_reason"]) for final in finals]
    cells = [int(final["cells_visited"]) for final in finals]
    traces = [
        GateTrace(np.asarray(c), np.asarray(r, dtype=bool), np.asarray(v, dtype=bool), ending)
        for c, r, v, ending in zip(chances, in_reach, in_view, endings, strict=True)
    ]
    out_of_view = [
        trace.in_reach & ~trace.in_view & np.asarray(s, dtype=bool)
        for trace, s in zip(traces, seen, strict=True)
    ]
    return FoundCalls(
        near_steps=sum(int(trace.in_reach.sum()) for trace in traces),
        near_probability=_mean_where(traces, lambda t: t.in_reach),
        far_steps=sum(int((~trace.in_reach).sum()) for trace in traces),
        far_probability=_mean_where(traces, lambda t: ~t.in_reach),
        endings=dict(Counter(endings)),
        reached=sum(bool(trace.in_reach.any()) for trace in traces),
        seen_in_reach=sum(bool((trace.in_reach & trace.in_view).any()) for trace in traces),
        in_view_steps=sum(int((trace.in_reach & trace.in_view).sum()) for trace in traces),
        in_view_probability=_mean_where(traces, lambda t: t.in_reach & t.in_view),
        missed_in_reach=sum(
            bool(trace.in_reach.any()) and trace.ending != "success" for trace in traces
        ),
        seen_out_of_view_steps=sum(int(where.sum()) for where in out_of_view),
        seen_out_of_view_probability=_mean_over(traces, out_of_view),
        saw_goal=sum(bool(final["current_goal_seen"]) for final in finals),
        cells_visited=_mean(cells),
        cells_at_step_limit=_mean(
            [n for n, ending in zip(cells, endings, strict=True) if ending == "max_steps"]
        ),
        gate_endings={
            f"{gate:g}": counts
            for gate, counts in gate_endings(traces, gates, policy.found_gate).items()
        }
        if policy.found_head is not None
        else {},
    )


def probe_scores(
    policy: RecurrentPolicy,
    train: VisionFrames,
    held_out: VisionFrames,
    settings: VisionPretraining,
) -> list[BandScores]:
    """A linear probe of the frozen image embedding: trained on ``train``, scored by band on
    ``held_out`` (the encoder is left as it was)."""
    encoder = policy.image_encoder
    assert encoder is not None
    head = PlaceHead(encoder.out_dim).to(policy.device)
    fit_head(encoder, head, train, settings, train_encoder=False)
    predicted = predict_goal_in_view(encoder, head, held_out)
    return band_scores(predicted, goal_in_view(held_out), held_out.distance)


def recogniser_scores(policy: RecurrentPolicy, held_out: VisionFrames) -> list[BandScores] | None:
    """ObjRecogMap's recogniser on ``held_out``: "the goal shows" where it names the frame's
    goal category (None for an agent without one). Its training label was narrower: the
    nearest goal within 2.5 m."""
    memory, encoder = policy.memory, policy.image_encoder
    if not isinstance(memory, ObjRecogMap) or encoder is None:
        return None
    predicted = recogniser_answers(memory, encoder, held_out) == held_out.goal + 1
    return band_scores(predicted, goal_in_view(held_out), held_out.distance)


def view_frames(
    config: EnvConfig, settings: VisionPretraining, progress: bool = False
) -> tuple[VisionFrames, VisionFrames]:
    """Probe frames: ``settings.samples`` of train houses, ``settings.held_out`` of val."""
    train = replace(config, split="train")
    return (
        sample_frames(train, settings.samples, settings.seed, settings, "train", progress),
        sample_frames(config, settings.held_out, settings.seed + 1, settings, "val", progress),
    )


def _mean_where(traces: Sequence[GateTrace], where: Callable[[GateTrace], np.ndarray]) -> float:
    """The mean probability over the steps of ``traces`` where ``where`` holds (nan: none)."""
    return _mean_over(traces, [where(trace) for trace in traces])


def _mean_over(traces: Sequence[GateTrace], masks: Sequence[np.ndarray]) -> float:
    """The mean probability over the steps of ``traces`` its mask in ``masks`` picks."""
    chosen = [trace.probability[mask] for trace, mask in zip(traces, masks, strict=True)]
    values = np.concatenate(chosen) if chosen else np.empty(0)
    return float(values.mean()) if values.size else math.nan


def _mean(values: Sequence[int]) -> float:
    return float(np.mean(values)) if values else math.nan
