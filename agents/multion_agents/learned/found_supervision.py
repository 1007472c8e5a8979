"""``--found-supervision COEF``: the policy's FOUND probability taught where FOUND would succeed.

`multion diagnose` on the pilot's `no-map` runs (issue 51) showed the agents that must see
failing at the decision, not at the seeing: a linear probe of the frozen image embedding tells
"the goal shows within 1.5 m" with recall 0.86 and precision 0.85, yet the policy's mean
P(FOUND) was 0.00 both within 1.5 m of the goal and farther. PPO alone rarely samples FOUND at
the goal, so it seldom learns what calling it there is worth.

This adds a supervised term to PPO's loss, from the ``goal_distance`` oracle sensor (geodesic
metres to the current goal), which only training receives: a class-balanced binary
cross-entropy of P(FOUND) against "FOUND would succeed now" (the goal within the task's
success distance). Positives are rare (a few % of steps), so each class weighs half over each
rollout (:func:`class_weights`). The
policy never reads the sensor; it is off in the paper's recipe, and evaluation never has it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import torch
from torch import Tensor

from multion_agents.learned.goal_heads import GOAL_VECTOR, goal_seen
from multion_agents.learned.train_settings import Args
from multion_client.constants import Action

FOUND_LABEL_SENSOR = "goal_distance"


IN_VIEW_SENSOR = "goal_mask"
"""``--found-head``'s second label sensor: whether the frame shows the current goal."""


def found_label_sensors(args: Args) -> tuple[str, ...]:
    """The training-only sensors a run's rollouts carry to learn FOUND from: ``goal_distance``
    for ``--found-supervision``, and for ``--found-head`` too the one :func:`head_may_know`
    reads, ``goal_mask`` (``in-view``) or ``goal_vector`` (``seen``); none without."""
    if args.found_head > 0:
        may_know = GOAL_VECTOR if args.found_head_label == "seen" else IN_VIEW_SENSOR
        return (FOUND_LABEL_SENSOR, may_know)
    return (FOUND_LABEL_SENSOR,) if args.found_supervision > 0 else ()


def head_may_know(frames: Mapping[str, Tensor], label: str) -> Tensor:
    """Per step (T, B), where ``--found-head-label`` ``label`` lets the FOUND head learn that
    FOUND would succeed: where the frame shows the goal (``in-view``), or where the goal has
    been in view at some step of the episode so far (``seen``: ``goal_vector``'s first value),
    so that an agent standing on a goal the frame no longer shows may still call it."""
    if label == "seen":
        return goal_seen(frames[GOAL_VECTOR])
    return goal_in_view(frames[IN_VIEW_SENSOR], frames["goal"])


def goal_in_view(goal_mask: Tensor, goal: Tensor) -> Tensor:
    """Per frame, whether any pixel of ``goal_mask`` (T, B, H, W; category + 1, 0 for none)
    shows the current ``goal`` category (T, B)."""
    wanted = (goal.long() + 1).reshape(*goal.shape[:2], 1)
    return (goal_mask.flatten(2).long() == wanted).any(-1)


def found_labels(distance: Tensor, success_distance: float) -> Tensor:
    """1.0 where FOUND would succeed (the current goal within ``success_distance``), else 0.0;
    one per step, from the ``goal_distance`` sensor's (..., 1) readings."""
    return (distance.reshape(-1) <= success_distance).float()


@dataclass(frozen=True)
class FoundTargets:
    """What the loss needs of a rollout (or of its mini-batch: ``labels`` picked, ``weights``
    kept): ``labels`` (T, B) 1.0 where FOUND would succeed; ``weights`` the whole rollout's
    :func:`class_weights`, None where it lacks a class (no FOUND term then)."""

    labels: Tensor
    weights: tuple[float, float] | None


def found_targets(
    distance: Tensor, success_distance: float, may_know: Tensor | None = None
) -> FoundTargets:
    """The targets of a rollout from its ``goal_distance`` readings (T, B, 1), weighted by
    :func:`class_weights` (``--found-supervision``); with ``may_know`` (T, B;
    :func:`head_may_know`), the FOUND head's: only where the agent may know the goal is there
    (it shows, or has shown), unweighted (:func:`found_head_loss`)."""
    labels = found_labels(distance, success_distance).view(distance.shape[:2])
    if may_know is None:
        return FoundTargets(labels, class_weights(labels))
    return FoundTargets(labels * may_know.to(labels.dtype), None)


def class_weights(labels: Tensor) -> tuple[float, float] | None:
    """Per-step weights (positive, negative) that give each class half of the loss over
    ``labels`` (a whole rollout's): ``N / (2 N_pos)`` and ``N / (2 N_neg)``; None where a class
    is absent (a rollout with no step at a goal has nothing to teach FOUND from).

    Balancing over the rollout, not over each mini-batch, is what makes the classes weigh half
    each over an update: most mini-batches hold no positive, and balanced on its own each of
    them taught "never FOUND" with the whole weight (issue 51's pilot: P(FOUND) at the
    positives fell from 0.02 to 0.0002 with a coefficient of 10)."""
    total = labels.numel()
    positives = int((labels > 0.5).sum())  # any shape: one label per step
    if positives == 0 or positives == total:
        return None
    return total / (2.0 * positives), total / (2.0 * (total - positives))


def found_loss(logits: Tensor, labels: Tensor, weights: tuple[float, float]) -> Tensor:
    """Weighted binary cross-entropy of P(FOUND) (from action ``logits``, (..., A)) against
    ``labels`` (one per step), averaged over the steps: ``weights`` (positive, negative) per
    step, from :func:`class_weights` of the rollout the steps belong to."""
    flat = logits.reshape(-1, logits.shape[-1]).float()
    log_probs = torch.log_softmax(flat, dim=-1)
    found = int(Action.FOUND)
    log_found = log_probs[:, found]
    others = torch.cat([log_probs[:, :found], log_probs[:, found + 1 :]], dim=1)
    log_not_found = torch.logsumexp(others, dim=1)
    positive = labels.reshape(-1) > 0.5
    terms = torch.where(positive, -weights[0] * log_found, -weights[1] * log_not_found)
    return terms.mean()


def found_head_loss(found_logit: Tensor, labels: Tensor, positive_weight: float = 1.0) -> Tensor:
    """``--found-head``'s loss: the binary cross-entropy of the head's logits (one per step)
    against ``labels``. Unweighted (``positive_weight`` 1), its probability estimates how likely
    FOUND is to succeed and the gate (probability above 0.5) opens only where success is the
    likelier outcome: a wrong FOUND ends the episode, a FOUND called one step late costs a step.
    ``positive_weight`` (``--found-head-positive-weight``) weighs the positive steps more."""
    weight = torch.tensor(positive_weight, device=found_logit.device)
    return torch.nn.functional.binary_cross_entropy_with_logits(
        found_logit.reshape(-1).float(), labels.reshape(-1), pos_weight=weight
    )


def found_probabilities(logits: Tensor, found_logit: Tensor | None) -> Tensor:
    """Per step, how likely the policy is to call FOUND: the head's probability where it has
    one (``found_logit``), else the actor's softmax probability of FOUND."""
    if found_logit is not None:
        return torch.sigmoid(found_logit.reshape(-1).float())
    flat = logits.reshape(-1, logits.shape[-1]).float()
    return torch.softmax(flat, dim=-1)[:, int(Action.FOUND)]


def mean_where(values: Tensor, where: Tensor) -> Tensor | None:
    """The mean of ``values`` (one per step) where ``where`` holds; None where it never does."""
    where = where.reshape(-1)
    return values[where].mean() if where.any() else None
