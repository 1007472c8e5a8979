"""PPO and DD-PPO for the MultiON agents, in one file (in the style of cleanrl).

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
import time
from collections import deque
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch
from torch import Tensor, nn
from tqdm import tqdm

from multion.config.ranges import ConfigError
from multion_agents.agent import merge_overrides
from multion_agents.learned.checkpoint import (
    CheckpointError,
    build_policy,
    load_checkpoint,
    restore_random_states,
    save_checkpoint,
    with_legacy_fields,
)
from multion_agents.learned.distributed import (
    average_gradients,
    broadcast_parameters,
    cores_per_rank,
    init_distributed,
    select_device,
    sum_over_ranks,
    weights_digest,
)
from multion_agents.learned.env_groups import make_env_groups
from multion_agents.learned.models import model_spec
from multion_agents.learned.periodic_eval import evaluate_policy
from multion_agents.learned.policy import RecurrentPolicy, hidden_size_of
from multion_agents.learned.precision import update_precision
from multion_agents.learned.pretrain import check_map_pretraining, pretrain_map
from multion_agents.learned.rollout import Rollout, collect, compute_gae, start_episodes
from multion_agents.learned.rollout_envs import (
    NO_LABEL,
    SUMMARY_METRICS,
    check_curriculum,
    stage_config,
    training_env_config,
)
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_log import TrainingLog, plot_learning_curve
from multion_client.constants import Action

FOUND = int(Action.FOUND)


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
) -> dict[str, float]:
    """PPO's clipped-objective update on one rollout (``clip``: this update's clip range, by
    default ``args.clip``); gradients are averaged over DD-PPO ranks."""
    clip = args.clip if clip is None else clip
    num_envs = rollout.rewards.shape[1]
    groups = max(1, min(args.minibatches, num_envs))
    advantages = rollout.advantages
    if args.normalize_advantages:
        advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
    device = policy.device
    precision = update_precision(args.mixed_precision, device, optimizer)
    totals: dict[str, float] = {}
    updates = 0
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
            with precision.autocast():
                loss, losses = ppo_loss(policy, minibatch, clip, args)
            optimizer.zero_grad(set_to_none=False)
            precision.backward(loss)
            average_gradients(policy)
            precision.unscale(optimizer)
            grad_norm = nn.utils.clip_grad_norm_(policy.parameters(), args.max_grad_norm)
            precision.step(optimizer)
            stats = {k: v.item() if v is not None else math.nan for k, v in losses.items()}
            stats["grad_norm"] = float(grad_norm)
            for key, value_ in stats.items():
                totals[key] = totals.get(key, 0.0) + value_
            updates += 1
    return {k: v / updates for k, v in totals.items()}


def ppo_loss(
    policy: RecurrentPolicy, batch: Rollout, clip: float, args: Args
) -> tuple[Tensor, dict[str, Tensor | None]]:
    """PPO's loss on one recurrent mini-batch (every tensor on the policy's device): the
    clipped surrogate, the clipped value loss (clipped by the same, possibly decayed, ``clip``),
    the entropy bonus, the model's auxiliary loss and the imitation loss; and those terms for
    logging."""
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
    loss = policy_loss + args.value_coef * value_loss - args.entropy_coef * entropy_mean
    if aux is not None:
        loss = loss + args.aux_coef * aux
    imitation = None
    if args.imitation_coef > 0 and batch.expert_actions.numel():
        labelled = batch.expert_actions != NO_LABEL
        if labelled.any():
            imitation = nn.functional.cross_entropy(
                replay.logits[labelled], batch.expert_actions[labelled]
            )
            loss = loss + args.imitation_coef * imitation
    return loss, {
        "policy_loss": policy_loss.detach(),
        "value_loss": value_loss.detach(),
        "entropy": entropy_mean.detach(),
        "aux_loss": aux.detach() if aux is not None else None,
        "imitation_loss": imitation.detach() if imitation is not None else None,
        "clip_fraction": ((ratio - 1).abs() > clip).float().mean().detach(),
    }


# ---------------------------------------------------------------------- the training loop
def train(args: Args) -> dict[str, Any]:
    """Run (or resume) a training run; returns a summary of the last update."""
    from multion.config.codec import env_config_from_dict, env_config_to_dict
    from multion.config.datasets import parse_task

    spec = model_spec(args.agent)
    num_goals = parse_task(args.task)
    device = select_device(args.device)
    rank, world = init_distributed(device)
    act_threads = max(1, args.threads)
    update_threads = args.update_threads or cores_per_rank()
    torch.set_num_threads(act_threads)
    out = Path(args.out)
    env_config = training_env_config(
        num_goals,
        spec.train_sensors,
        args.image_size,
        "train",
        spec.config_overrides,
        args.max_steps,
        args.dataset,
    )
    env_config = merge_overrides(env_config, args.env_overrides)
    env_config["episodes_per_scene"] = args.episodes_per_scene
    # every field spelled out: the checkpoint then fixes the map geometry, crop size and
    # camera even if the env's defaults change later
    env_config = env_config_to_dict(env_config_from_dict(env_config))
    check_curriculum(args.curriculum, env_config)
    check_map_pretraining(args.pretrain_map, args.agent, spec.sensors)
    torch.manual_seed(args.seed)  # identical initial weights on every rank
    policy = build_policy(args.agent, env_config, args.hidden_size).to(device)
    if args.found_prior is not None:
        set_found_prior(policy, args.found_prior)
    optimizer = torch.optim.Adam(policy.parameters(), lr=args.learning_rate, eps=1e-5)
    update, frames = 0, 0
    checkpoint_path = out / "checkpoint.pt"
    if args.resume:
        payload = load_checkpoint(checkpoint_path)
        stored = env_config_from_dict(with_legacy_fields(payload["env_config"]))
        if payload["agent"] != args.agent or stored != env_config_from_dict(env_config):
            raise CheckpointError(
                f"{checkpoint_path} was trained with agent {payload['agent']!r} and env config "
                f"{payload['env_config']}; this run asks for {args.agent!r} and {env_config}"
            )
        trained_with = hidden_size_of(payload["model"])
        if trained_with != args.hidden_size:
            raise CheckpointError(
                f"{checkpoint_path} was trained with a GRU of {trained_with} units; this run "
                f"asks for {args.hidden_size} (resume with --hidden-size {trained_with})"
            )
        policy.load_state_dict(payload["model"])
        optimizer.load_state_dict(payload["optimizer"])
        update, frames = payload["update"], payload["frames"]
        restore_random_states(payload)
    elif args.pretrain_map.steps > 0:
        if rank == 0:
            pretrain_map(policy, env_config, args.pretrain_map, Path(args.out), args.progress)
            fresh = torch.optim.Adam(policy.parameters(), lr=args.learning_rate, eps=1e-5)
            _save(checkpoint_path, policy, fresh, args, env_config, update, frames)
    broadcast_parameters(policy)
    torch.manual_seed(args.seed * 7919 + update * 104729 + rank)  # per-rank action sampling
    frames_per_update = args.rollout_steps * args.envs * world
    total_updates = math.ceil(args.frames / frames_per_update)
    servers = tuple(args.servers[rank::world]) or tuple(args.servers)
    stage = stage_config(env_config, args.curriculum, frames)
    imitate = args.imitation_coef > 0
    envs = make_env_groups(stage, args.envs, servers, imitate, args.envs_per_process)
    log = TrainingLog(out, tensorboard=args.tensorboard) if rank == 0 else None
    if log is not None and args.resume:
        log.rewind(update)
    window: deque[dict[str, float]] = deque(maxlen=100)
    try:
        live = start_episodes(envs, policy, _reset_seed(args, update, rank))
        bar = tqdm(
            total=total_updates * frames_per_update,
            initial=frames,
            unit="frame",
            unit_scale=True,
            desc=f"train {args.agent} {args.task}",
            disable=not (args.progress and rank == 0),
        )
        summary: dict[str, Any] = {}
        while update < total_updates:
            wanted = stage_config(env_config, args.curriculum, frames)
            if wanted != stage:
                # the curriculum's next stage: new environments, fresh episodes and memories
                envs.close()
                stage = wanted
                envs = make_env_groups(stage, args.envs, servers, imitate, args.envs_per_process)
                live = start_episodes(envs, policy, _reset_seed(args, update, rank))
            tick = time.perf_counter()
            rollout, next_value, timing = collect(envs, policy, live, args.rollout_steps, window)
            compute_gae(rollout, next_value, args.gamma, args.gae_lambda)
            update_tick = time.perf_counter()
            torch.set_num_threads(update_threads)
            learning_rate, clip = schedule(args, update, total_updates)
            for group in optimizer.param_groups:
                group["lr"] = learning_rate
            try:
                stats = ppo_update(policy, optimizer, rollout, args, clip)
            finally:
                torch.set_num_threads(act_threads)
            update_seconds = time.perf_counter() - update_tick
            update += 1
            frames += frames_per_update
            seconds = time.perf_counter() - tick
            summary = {
                "update": update,
                "frames": frames,
                "fps": frames_per_update / seconds,
                "sim_seconds": timing.sim_seconds,
                "act_seconds": timing.act_seconds,
                "update_seconds": update_seconds,
                "learning_rate": learning_rate,
                "clip": clip,
                "max_geodesic": stage["online_max_geodesic"],
                **_window_means(window, device),
                "expert_agreement": _agreement(rollout),
                **stats,
            }
            bar.update(frames_per_update)
            if log is not None:
                log.write("progress", summary)
                bar.set_postfix(
                    success=f"{100 * summary['train_success']:.0f}%" if summary["episodes"] else "-"
                )
                final = update == total_updates
                if update % args.checkpoint_every == 0 or final:
                    _save(checkpoint_path, policy, optimizer, args, env_config, update, frames)
                due = (
                    args.eval_every
                    and frames // args.eval_every != (frames - frames_per_update) // args.eval_every
                )
                if args.eval_episodes > 0 and (due or final):
                    result = evaluate_policy(
                        policy, args.eval_episodes, args.seed, env_config, num_goals
                    )
                    log.write("eval", {"frames": frames, "update": update, **result})
                    plot_learning_curve(out, f"{args.agent} on {args.task}")
        bar.close()
        if log is not None:
            plot_learning_curve(out, f"{args.agent} on {args.task}")
        # a resumed run that already holds its frames trains nothing: say where it stands
        return {"frames": frames, **summary, "weights_sha256": weights_digest(policy)}
    except BaseException:
        # interrupted (Ctrl-C, SIGTERM) in the middle of a worker's reply: the half-read pipe
        # would make close() wait for pending calls forever, so the workers are ended instead
        envs.close(terminate=True)
        raise
    finally:
        envs.close()  # a no-op once closed
        if log is not None:
            log.close()


def _reset_seed(args: Args, update: int, rank: int) -> int:
    """The seed of a reset of all of this rank's environments (at a start, resume or stage)."""
    return args.seed * 100_003 + update * 1_009 + rank * args.envs


def _agreement(rollout: Rollout) -> float:
    """The fraction of labelled steps where the learner took the expert's action (nan: none)."""
    labelled = rollout.expert_actions != NO_LABEL
    if not rollout.expert_actions.numel() or not labelled.any():
        return math.nan
    return float((rollout.actions[labelled] == rollout.expert_actions[labelled]).float().mean())


def _window_means(window: deque[dict[str, float]], device: torch.device) -> dict[str, float]:
    names = [*SUMMARY_METRICS, "return"]
    sums = [sum(e.get(k, 0.0) for e in window) for k in names] + [float(len(window))]
    sums = sum_over_ranks(sums, device)
    count = sums[-1]
    means = {
        f"train_{k}": (s / count if count else math.nan)
        for k, s in zip(names, sums[:-1], strict=True)
    }
    return {"episodes": count, **means}


def _save(
    path: Path,
    policy: RecurrentPolicy,
    optimizer: torch.optim.Optimizer,
    args: Args,
    env_config: dict[str, Any],
    update: int,
    frames: int,
) -> None:
    save_checkpoint(
        path,
        {
            "model": policy.state_dict(),
            "optimizer": optimizer.state_dict(),
            "agent": args.agent,
            "task": args.task,
            "env_config": env_config,
            "args": asdict(args),
            "update": update,
            "frames": frames,
        },
    )
