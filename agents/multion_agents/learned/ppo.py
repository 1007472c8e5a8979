"""PPO and DD-PPO's update and loss for the MultiON agents (in the style of cleanrl; the
training loop around them is :mod:`multion_agents.learned.training_run`).

One process trains with PPO. Several processes started by ``torchrun`` train with DD-PPO
(Wijmans et al. 2020): every rank steps its own environments, computes gradients on its own
rollouts, and the gradients are averaged with ``all_reduce`` before each optimiser step, so
the ranks' weights stay identical (gloo on CPU, NCCL on GPU). The same command works on one
core, one machine or many.

Recurrent mini-batches: the rollout's environments are split into ``minibatches`` groups and
each group's 128-step sequences are replayed from the state saved at the start of the rollout.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from multion.config.ranges import ConfigError
from multion.config.task import TaskConfig
from multion_agents.learned.distributed import average_gradients
from multion_agents.learned.found_gate import FOUND
from multion_agents.learned.found_supervision import (
    FOUND_LABEL_SENSOR,
    FoundTargets,
    found_head_loss,
    found_label_sensors,
    found_loss,
    found_probabilities,
    found_targets,
    head_may_know,
    mean_where,
)
from multion_agents.learned.policy import RecurrentPolicy
from multion_agents.learned.precision import update_precision
from multion_agents.learned.rollout import Rollout
from multion_agents.learned.rollout_envs import NO_LABEL
from multion_agents.learned.train_settings import Args

SUCCESS_DISTANCE = TaskConfig().success_distance


def set_found_prior(policy: RecurrentPolicy, probability: float) -> None:
    """Set the actor's biases so that the untrained policy (near-zero actor weights) calls FOUND
    with ``probability`` and spreads the rest evenly over the other actions."""
    if not 0.0 < probability < 1.0:
        raise ConfigError(f"found_prior must be in (0, 1), got {probability}")
    others = policy.actor.bias.numel() - 1
    with torch.no_grad():
        policy.actor.bias.fill_(math.log((1.0 - probability) / others))
        policy.actor.bias[FOUND] = math.log(probability)


def linear_decay(update: int, total_updates: int) -> float:
    """The factor of a hyper-parameter decayed linearly to 0: 1 at the first update (index 0),
    ``1 - update / total`` later. Derived from the update count, so a resumed run continues
    the schedule exactly."""
    return max(0.0, 1.0 - update / max(1, total_updates))


def schedule(args: Args, update: int, total_updates: int) -> tuple[float, float]:
    """(learning rate, clip range) of update number ``update`` (0-based)."""
    factor = linear_decay(update, total_updates)
    learning_rate = args.learning_rate * (factor if args.lr_decay else 1.0)
    clip = args.clip * (factor if args.clip_decay else 1.0)
    return learning_rate, clip


def ppo_update(
    policy: RecurrentPolicy,
    optimizer: torch.optim.Optimizer,
    rollout: Rollout,
    args: Args,
    clip: float | None = None,
    success_distance: float = SUCCESS_DISTANCE,
    measure_gradients: bool = False,
) -> dict[str, float]:
    """PPO's clipped-objective update on one rollout (``clip``: this update's clip range, by
    default ``args.clip``; ``success_distance``: the task's, for ``--found-supervision``);
    gradients are averaged over DD-PPO ranks. ``measure_gradients``: also log, on the first
    mini-batch, each loss term's gradient norm on the GRU (:func:`gru_gradient_norms`)."""
    clip = args.clip if clip is None else clip
    num_envs = rollout.rewards.shape[1]
    groups = max(1, min(args.minibatches, num_envs))
    advantages = rollout.advantages
    # logged before normalising: against the entropy bonus it says how strong PPO's signal is
    advantage_std = float(advantages.std())
    if args.normalize_advantages:
        advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
    targets = None
    frames = rollout.frames
    label_sensors = found_label_sensors(args)
    if label_sensors and all(k in frames for k in label_sensors):
        may_know = head_may_know(frames, args.found_head_label) if args.found_head else None
        targets = found_targets(frames[FOUND_LABEL_SENSOR], success_distance, may_know)
    device = policy.device
    precision = update_precision(args.mixed_precision, device, optimizer)
    totals: dict[str, float] = {}
    counts: dict[str, int] = {}
    policy.train()
    for _ in range(args.epochs):
        order = torch.randperm(num_envs)
        for chunk in order.chunk(groups):

            def pick(x: Tensor, chunk: Tensor = chunk) -> Tensor:
                return x[:, chunk].to(device)

            minibatch = Rollout(
                frames={k: pick(v) for k, v in rollout.frames.items()},
                prev_actions=pick(rollout.prev_actions),
                starts=pick(rollout.starts),
                actions=pick(rollout.actions),
                logprobs=pick(rollout.logprobs),
                values=pick(rollout.values),
                rewards=pick(rollout.rewards),
                dones=pick(rollout.dones),
                initial_state={k: v[chunk].to(device) for k, v in rollout.initial_state.items()},
                advantages=pick(advantages),
                returns=pick(rollout.returns),
                expert_actions=pick(rollout.expert_actions)
                if rollout.expert_actions.numel()
                else rollout.expert_actions,
            )
            found = None if targets is None else FoundTargets(pick(targets.labels), targets.weights)
            with precision.autocast():
                terms, losses = ppo_terms(policy, minibatch, clip, args, found)
            loss = sum_terms(terms)
            # on the first mini-batch only: it costs a backward pass per term
            measured = gru_gradient_norms(policy, terms) if measure_gradients and not totals else {}
            optimizer.zero_grad(set_to_none=False)
            precision.backward(loss)
            average_gradients(policy)
            precision.unscale(optimizer)
            grad_norm = nn.utils.clip_grad_norm_(policy.parameters(), args.max_grad_norm)
            precision.step(optimizer)
            stats = {k: v.item() if v is not None else None for k, v in losses.items()}
            stats["grad_norm"] = float(grad_norm)
            stats.update(measured)
            for key, value_ in stats.items():
                totals.setdefault(key, 0.0)
                if value_ is not None:
                    totals[key] += value_
                    counts[key] = counts.get(key, 0) + 1
    # a term some mini-batches lack (no FOUND positive, no labelled step) is averaged over those
    # that have it; nan where none has
    means = {k: total / counts[k] if k in counts else math.nan for k, total in totals.items()}
    return {**means, "advantage_std": advantage_std}


def ppo_loss(
    policy: RecurrentPolicy,
    batch: Rollout,
    clip: float,
    args: Args,
    found: FoundTargets | None = None,
) -> tuple[Tensor, dict[str, Tensor | None]]:
    """PPO's loss on one recurrent mini-batch: the sum of :func:`ppo_terms`, and the values
    logged."""
    terms, losses = ppo_terms(policy, batch, clip, args, found)
    return sum_terms(terms), losses


LOSS_TERMS = ("policy", "value", "aux", "goal_heads", "found", "imitation")
"""The weighted terms of PPO's loss (:func:`ppo_terms`), in the order they are summed."""


def sum_terms(terms: dict[str, Tensor]) -> Tensor:
    """The loss: the weighted terms' sum, in :data:`LOSS_TERMS`' order (``policy`` is always
    there)."""
    loss = terms["policy"]
    for name in LOSS_TERMS[1:]:
        if name in terms:
            loss = loss + terms[name]
    return loss


def gru_gradient_norms(policy: RecurrentPolicy, terms: dict[str, Tensor]) -> dict[str, float]:
    """Each weighted loss term's gradient norm on the GRU's weights (``gru_gradient_<term>``),
    before clipping. The GRU is what every term trains; where the supervised terms' gradients
    dwarf the policy's, the clipped step is theirs."""
    weights = [p for p in policy.gru.parameters() if p.requires_grad]
    norms = {}
    for name, term in terms.items():
        grads = torch.autograd.grad(term, weights, retain_graph=True, allow_unused=True)
        present = [g.float().pow(2).sum() for g in grads if g is not None]
        norms[f"gru_gradient_{name}"] = float(torch.stack(present).sum().sqrt()) if present else 0.0
    return norms


def ppo_terms(
    policy: RecurrentPolicy,
    batch: Rollout,
    clip: float,
    args: Args,
    found: FoundTargets | None = None,
) -> tuple[dict[str, Tensor], dict[str, Tensor | None]]:
    """PPO's loss on one recurrent mini-batch (every tensor on the policy's device), as its
    weighted terms (:data:`LOSS_TERMS`, those in use): ``policy``, the clipped surrogate less
    the entropy bonus; ``value``, the clipped value loss (clipped by the same, possibly decayed,
    ``clip``); the model's auxiliary loss, the goal heads', the FOUND supervision's and the
    imitation loss; and the values logged. ``found``: the FOUND supervision's targets
    for this batch, weighted by the whole rollout's classes (``ppo_update`` makes them)."""
    replay = policy.evaluate_actions(
        batch.frames, batch.prev_actions, batch.starts, batch.initial_state, batch.actions
    )
    logprob, entropy, value, aux = (
        replay.logprob,
        replay.entropy,
        replay.value,
        replay.auxiliary_loss,
    )
    ratio = torch.exp(logprob - batch.logprobs)
    adv = batch.advantages
    policy_loss = -torch.min(ratio * adv, ratio.clamp(1 - clip, 1 + clip) * adv).mean()
    old_values, returns = batch.values, batch.returns
    clipped = old_values + (value - old_values).clamp(-clip, clip)
    value_loss = 0.5 * torch.max((value - returns) ** 2, (clipped - returns) ** 2).mean()
    entropy_mean = entropy.mean()
    terms = {
        "policy": policy_loss - args.entropy_coef * entropy_mean,
        "value": args.value_coef * value_loss,
    }
    if aux is not None:
        terms["aux"] = args.aux_coef * aux
    heads = replay.goal_losses
    if heads is not None:
        terms["goal_heads"] = args.goal_head_coef * heads.total
    found_term = found_at_goal = found_elsewhere = None
    if found is not None:
        at_goal = found.labels.reshape(-1) > 0.5
        with torch.no_grad():
            chances = found_probabilities(replay.logits, replay.found_logit)
        found_at_goal = mean_where(chances, at_goal)
        found_elsewhere = mean_where(chances, ~at_goal)
        if replay.found_logit is not None and args.found_head > 0:
            found_term = found_head_loss(
                replay.found_logit, found.labels, args.found_head_positive_weight
            )
            terms["found"] = args.found_head * found_term
        elif found.weights is not None and args.found_supervision > 0:
            found_term = found_loss(replay.logits, found.labels, found.weights)
            terms["found"] = args.found_supervision * found_term
    imitation = None
    if args.imitation_coef > 0 and batch.expert_actions.numel():
        labelled = batch.expert_actions != NO_LABEL
        if replay.found_logit is not None:
            # a FOUND head decides FOUND (the replay's logits are gated): the actor is taught
            # the expert's movements where the gate left it to move; FOUND labels teach nothing
            labelled &= (batch.expert_actions != FOUND) & (batch.actions != FOUND)
        if labelled.any():
            imitation = nn.functional.cross_entropy(
                replay.logits[labelled], batch.expert_actions[labelled]
            )
            terms["imitation"] = args.imitation_coef * imitation
    return terms, {
        "policy_loss": policy_loss.detach(),
        "value_loss": value_loss.detach(),
        "entropy": entropy_mean.detach(),
        "aux_loss": aux.detach() if aux is not None else None,
        "imitation_loss": imitation.detach() if imitation is not None else None,
        "found_loss": found_term.detach() if found_term is not None else None,
        "found_positive_share": found.labels.mean() if found is not None else None,
        "found_prob_at_goal": found_at_goal,
        "found_prob_elsewhere": found_elsewhere,
        "clip_fraction": ((ratio - 1).abs() > clip).float().mean().detach(),
        "goal_seen_loss": heads.seen.detach() if heads is not None else None,
        "goal_direction_loss": heads.direction.detach() if heads is not None else None,
        "goal_distance_loss": heads.distance.detach() if heads is not None else None,
        "goal_seen_share": heads.seen_share.detach() if heads is not None else None,
    }
