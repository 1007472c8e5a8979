"""A training run as an object (PPO on one process, DD-PPO under ``torchrun``).

Its life: :meth:`TrainingRun.start` (a fresh policy, map pretraining when asked) or
:meth:`TrainingRun.resume` (the policy, optimiser, counters and random states of
``OUT/checkpoint.pt``) builds the policy and starts the environments; each :meth:`~TrainingRun.update`
collects one rollout and makes one PPO update (switching to the curriculum's next stage first when
its frames are done), then calls the run's after-update hooks in order: the progress row, the
checkpoint when due, the val evaluation when due (rank 0 only; the evaluation is passed in, as
``multion train`` does); :meth:`~TrainingRun.finish` draws the learning curve and returns the last
update's summary; :meth:`~TrainingRun.close` (or leaving the ``with`` block) ends the workers.
:func:`train` does all of it.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol

import torch
from tqdm import tqdm

from multion.config.codec import env_config_from_dict, env_config_to_dict
from multion.config.datasets import parse_task
from multion.config.ranges import ConfigError
from multion.config.task import EnvConfig
from multion_agents.agent import merge_overrides
from multion_agents.learned.checkpoint import (
    CheckpointError,
    check_recipe_options,
    load_checkpoint,
    restore_random_states,
    save_checkpoint,
    with_legacy_fields,
)
from multion_agents.learned.distributed import (
    broadcast_parameters,
    cores_per_rank,
    init_distributed,
    select_device,
    weights_digest,
)
from multion_agents.learned.env_groups import EnvGroups, make_env_groups
from multion_agents.learned.episode_stats import window_means
from multion_agents.learned.found_supervision import found_label_sensors
from multion_agents.learned.goal_heads import GOAL_VECTOR
from multion_agents.learned.learned_maps import ObjRecogMap
from multion_agents.learned.models import build_policy, model_spec
from multion_agents.learned.policy import POSE_SENSORS, RecurrentPolicy, hidden_size_of
from multion_agents.learned.ppo import ppo_update, schedule, set_found_prior
from multion_agents.learned.pretrain import check_map_pretraining, pretrain_map
from multion_agents.learned.rollout import Rollout, collect, compute_gae, start_episodes
from multion_agents.learned.rollout_envs import (
    NO_LABEL,
    TrainingWrappers,
    check_curriculum,
    stage_config,
    training_env_config,
)
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_log import TrainingLog, plot_learning_curve
from multion_agents.learned.vision_pretrain import (
    check_vision_pretraining,
    freeze_image_encoder,
    pretrain_vision,
)

GRADIENT_NORMS_EVERY = 10
"""Every this many updates (the first included), ``progress.csv`` gets each loss term's gradient
norm on the GRU (``gru_gradient_*``, :func:`~multion_agents.learned.ppo.gru_gradient_norms`):
a backward pass per term on one mini-batch. Measured side by side (8 envs x 128 steps, 2026-11-29,
load ~5 from a training run): a measured update costs 1.13x a plain one for no-map, 1.03x for
proj-neural-map, so +1.3 % and +0.3 % of update time at this cadence."""

Evaluation = Callable[[RecurrentPolicy, EnvConfig], dict[str, float]]
"""The periodic val evaluation: the mean val metrics of the policy trained in ``EnvConfig``
(``multion train`` passes :class:`multion_agents.periodic_eval.ValEvaluation`)."""


class AfterUpdate(Protocol):
    """A hook called after every update with the run and that update's summary row."""

    def __call__(self, run: TrainingRun, summary: dict[str, Any]) -> None: ...


@dataclass(frozen=True)
class Placement:
    """Where this process trains: its device, its DD-PPO rank among ``world``, its threads."""

    device: torch.device
    rank: int
    world: int
    act_threads: int
    update_threads: int


class TrainingRun:
    """One training run in this process (one rank of a DD-PPO job): build it with
    :meth:`start` or :meth:`resume`, call :meth:`update` until :attr:`done`, then
    :meth:`finish` and :meth:`close`."""

    def __init__(
        self,
        args: Args,
        env_config: EnvConfig,
        policy: RecurrentPolicy,
        optimizer: torch.optim.Optimizer,
        placement: Placement,
        updates: int = 0,
        frames: int = 0,
        evaluation: Evaluation | None = None,
    ) -> None:
        self.args, self.env_config, self.placement = args, env_config, placement
        self.policy, self.optimizer = policy, optimizer
        self.updates, self.frames = updates, frames
        self.out = Path(args.out)
        self.checkpoint_path = self.out / "checkpoint.pt"
        self.frames_per_update = args.rollout_steps * args.envs * placement.world
        self.total_updates = math.ceil(args.frames / self.frames_per_update)
        self.summary: dict[str, Any] = {}
        self.window: deque[dict[str, float]] = deque(maxlen=100)
        rank, world = placement.rank, placement.world
        self._servers = tuple(args.servers[rank::world]) or tuple(args.servers)
        self.stage = stage_config(env_config, args.curriculum, frames, args.found_curriculum)
        self.envs = self._make_envs(self.stage)
        self.log: TrainingLog | None = None
        self.hooks: list[AfterUpdate] = []
        try:
            if rank == 0:
                self.log = TrainingLog(self.out, tensorboard=args.tensorboard)
                if args.resume:
                    self.log.rewind(updates)
                self.hooks = [ProgressRow(self.log), CheckpointWhenDue()]
                if args.eval_episodes > 0 and evaluation is not None:
                    self.hooks.append(EvaluationWhenDue(self.log, evaluation))
            self.live = start_episodes(self.envs, policy, self._reset_seed())
        except BaseException:
            self.close(terminate=True)
            raise
        self.bar = tqdm(
            total=self.total_updates * self.frames_per_update,
            initial=frames,
            unit="frame",
            unit_scale=True,
            desc=f"train {args.agent} {args.task}",
            disable=not (args.progress and rank == 0),
        )

    # ------------------------------------------------------------------ constructors
    @classmethod
    def start(cls, args: Args, evaluation: Evaluation | None = None) -> TrainingRun:
        """A new run: a fresh policy (seeded by ``args.seed``), pretrained on map crops
        first when ``args.pretrain_map`` asks (and checkpointed before any update)."""
        env_config, policy, optimizer, placement = _prepare(args, evaluation)
        pretrains = args.pretrain_map.steps > 0 or args.pretrain_vision.steps > 0
        if pretrains and placement.rank == 0:
            if args.pretrain_vision.steps > 0:
                pretrain_vision(
                    policy,
                    env_config,
                    args.pretrain_vision,
                    Path(args.out),
                    args.progress,
                    args.pretrain_recogniser,
                )
            if args.pretrain_map.steps > 0:
                pretrain_map(policy, env_config, args.pretrain_map, Path(args.out), args.progress)
            fresh = torch.optim.Adam(policy.parameters(), lr=args.learning_rate, eps=1e-5)
            checkpoint = Path(args.out) / "checkpoint.pt"
            save_run_checkpoint(checkpoint, policy, fresh, args, env_config, 0, 0)
        return cls._launched(args, env_config, policy, optimizer, placement, 0, 0, evaluation)

    @classmethod
    def resume(cls, args: Args, evaluation: Evaluation | None = None) -> TrainingRun:
        """The run saved in ``OUT/checkpoint.pt``, which must have been trained with the same
        agent, env config and GRU size; it continues where the checkpoint left off."""
        env_config, policy, optimizer, placement = _prepare(args, evaluation)
        path = Path(args.out) / "checkpoint.pt"
        payload = load_checkpoint(path)
        check_recipe_options(path, payload.get("args", {}), args)
        stored = env_config_from_dict(with_legacy_fields(payload["env_config"]))
        if payload["agent"] != args.agent or stored != env_config:
            raise CheckpointError(
                f"{path} was trained with agent {payload['agent']!r} and env config "
                f"{payload['env_config']}; this run asks for {args.agent!r} and "
                f"{env_config_to_dict(env_config)}"
            )
        trained_with = hidden_size_of(payload["model"])
        if trained_with != args.hidden_size:
            raise CheckpointError(
                f"{path} was trained with a GRU of {trained_with} units; this run "
                f"asks for {args.hidden_size} (resume with --hidden-size {trained_with})"
            )
        policy.load_state_dict(payload["model"])
        optimizer.load_state_dict(payload["optimizer"])
        restore_random_states(payload)
        updates, frames = payload["update"], payload["frames"]
        return cls._launched(
            args, env_config, policy, optimizer, placement, updates, frames, evaluation
        )

    @classmethod
    def _launched(
        cls,
        args: Args,
        env_config: EnvConfig,
        policy: RecurrentPolicy,
        optimizer: torch.optim.Optimizer,
        placement: Placement,
        updates: int,
        frames: int,
        evaluation: Evaluation | None,
    ) -> TrainingRun:
        broadcast_parameters(policy)
        if args.freeze_vision:  # after pretraining; a resume freezes the loaded weights again
            freeze_image_encoder(policy)
        # per-rank action sampling, continuing after a resume
        torch.manual_seed(args.seed * 7919 + updates * 104729 + placement.rank)
        return cls(args, env_config, policy, optimizer, placement, updates, frames, evaluation)

    # ------------------------------------------------------------------ the loop
    @property
    def done(self) -> bool:
        """Whether the run holds its ``--frames`` (a resumed run may hold them already)."""
        return self.updates >= self.total_updates

    def update(self) -> dict[str, Any]:
        """One rollout and one PPO update, then the hooks; returns the update's summary row."""
        args, placement = self.args, self.placement
        self._next_stage_when_due()
        tick = time.perf_counter()
        labels = found_label_sensors(args)
        rollout, next_value, timing = collect(
            self.envs, self.policy, self.live, args.rollout_steps, self.window, labels
        )
        compute_gae(rollout, next_value, args.gamma, args.gae_lambda)
        update_tick = time.perf_counter()
        torch.set_num_threads(placement.update_threads)
        learning_rate, clip = schedule(args, self.updates, self.total_updates)
        for group in self.optimizer.param_groups:
            group["lr"] = learning_rate
        try:
            stats = ppo_update(
                self.policy, self.optimizer, rollout, args, clip,
                self.env_config.task.success_distance,
                measure_gradients=self.updates % GRADIENT_NORMS_EVERY == 0,
            )  # fmt: skip
        finally:
            torch.set_num_threads(placement.act_threads)
        update_seconds = time.perf_counter() - update_tick
        self.updates += 1
        self.frames += self.frames_per_update
        seconds = time.perf_counter() - tick
        self.summary = {
            "update": self.updates,
            "frames": self.frames,
            "fps": self.frames_per_update / seconds,
            "sim_seconds": timing.sim_seconds,
            "act_seconds": timing.act_seconds,
            "update_seconds": update_seconds,
            "learning_rate": learning_rate,
            "clip": clip,
            "max_geodesic": self.stage.online_max_geodesic,
            "found_budget": self.stage.task.found_budget,
            **window_means(self.window, placement.device, self.env_config.task.success_distance),
            "expert_agreement": _agreement(rollout),
            **stats,
        }
        self.bar.update(self.frames_per_update)
        for hook in self.hooks:
            hook(self, self.summary)
        return self.summary

    def save(self) -> None:
        """Write the checkpoint (weights, optimiser, counters, random states, config)."""
        save_run_checkpoint(
            self.checkpoint_path,
            self.policy,
            self.optimizer,
            self.args,
            self.env_config,
            self.updates,
            self.frames,
        )

    def finish(self) -> dict[str, Any]:
        """Draw the learning curve; the frames done, the last update's summary (none when a
        resumed run already held its frames) and the weights' digest."""
        self.bar.close()
        if self.log is not None:
            plot_learning_curve(self.out, self.title)
        return {
            "frames": self.frames,
            **self.summary,
            "weights_sha256": weights_digest(self.policy),
        }

    @property
    def title(self) -> str:
        return f"{self.args.agent} on {self.args.task}"

    def close(self, terminate: bool = False) -> None:
        """End the environments' workers and close the log. ``terminate``: interrupted (Ctrl-C,
        SIGTERM), maybe in the middle of a worker's reply, whose half-read pipe would make a
        polite close wait forever, so the workers are ended instead."""
        self.envs.close(terminate=terminate)  # a no-op once closed
        if self.log is not None:
            self.log.close()

    def __enter__(self) -> TrainingRun:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        self.close(terminate=error is not None)

    # ------------------------------------------------------------------ internals
    def _make_envs(self, stage: EnvConfig) -> EnvGroups:
        # the workers (spawned processes or servers) read the config's wire form
        args = self.args
        return make_env_groups(
            env_config_to_dict(stage),
            args.envs,
            self._servers,
            TrainingWrappers(args.expert if args.imitation_coef > 0 else "", args.coverage_reward),
            args.envs_per_process,
        )

    def _next_stage_when_due(self) -> None:
        """The curriculum's next stage: new environments, fresh episodes and memories."""
        args = self.args
        wanted = stage_config(self.env_config, args.curriculum, self.frames, args.found_curriculum)
        if wanted == self.stage:
            return
        self.envs.close()
        self.stage = wanted
        self.envs = self._make_envs(wanted)
        self.live = start_episodes(self.envs, self.policy, self._reset_seed())

    def _reset_seed(self) -> int:
        """The seed of a reset of all of this rank's environments (at a start, resume or stage)."""
        args = self.args
        return args.seed * 100_003 + self.updates * 1_009 + self.placement.rank * args.envs


# ---------------------------------------------------------------------- after-update hooks
@dataclass
class ProgressRow:
    """Writes the update's summary to ``progress.csv`` (and TensorBoard) and shows the
    training success on the progress bar."""

    log: TrainingLog

    def __call__(self, run: TrainingRun, summary: dict[str, Any]) -> None:
        self.log.write("progress", summary)
        run.bar.set_postfix(
            success=f"{100 * summary['train_success']:.0f}%" if summary["episodes"] else "-"
        )


@dataclass
class CheckpointWhenDue:
    """Saves the checkpoint every ``--checkpoint-every`` updates and after the last one."""

    def __call__(self, run: TrainingRun, summary: dict[str, Any]) -> None:
        if run.updates % run.args.checkpoint_every == 0 or run.done:
            run.save()


@dataclass
class EvaluationWhenDue:
    """Evaluates the policy on val each time the frames cross a multiple of ``--eval-every``
    and after the last update; writes ``eval.csv`` and redraws the learning curve."""

    log: TrainingLog
    evaluation: Evaluation

    def __call__(self, run: TrainingRun, summary: dict[str, Any]) -> None:
        every, frames = run.args.eval_every, run.frames
        crossed = every and frames // every != (frames - run.frames_per_update) // every
        if not (crossed or run.done):
            return
        result = self.evaluation(run.policy, run.env_config)
        self.log.write("eval", {"frames": frames, "update": run.updates, **result})
        plot_learning_curve(run.out, run.title)


# ---------------------------------------------------------------------- the whole run
def train(args: Args, evaluation: Evaluation | None = None) -> dict[str, Any]:
    """Run (or, with ``args.resume``, resume) a training run to its ``--frames``; returns a
    summary of the last update. ``evaluation``: the periodic val evaluation, needed when
    ``args.eval_episodes`` > 0."""
    run = (
        TrainingRun.resume(args, evaluation) if args.resume else TrainingRun.start(args, evaluation)
    )
    with run:
        while not run.done:
            run.update()
        return run.finish()


def run_env_config(args: Args) -> EnvConfig:
    """The env config of the run ``args`` asks for, every field spelled out (the checkpoint
    then fixes the map geometry, crop size and camera even if the env's defaults change)."""
    spec = model_spec(args.agent)
    sensors = spec.train_sensors + ((GOAL_VECTOR,) if args.goal_heads else ())
    sensors += found_label_sensors(args)
    sensors += POSE_SENSORS if args.pose_input else ()
    # once each: options may ask for a sensor the model reads already (obj-recog-map's goal_mask
    # with --found-head, proj-neural-map's gps with --pose-input), which EnvConfig refuses twice
    config = training_env_config(
        parse_task(args.task),
        tuple(dict.fromkeys(sensors)),
        args.image_size,
        "train",
        spec.config_overrides,
        args.max_steps,
        args.dataset,
    )
    config = merge_overrides(config, args.env_overrides)
    config["episodes_per_scene"] = args.episodes_per_scene
    return env_config_from_dict(config)


def save_run_checkpoint(
    path: Path,
    policy: RecurrentPolicy,
    optimizer: torch.optim.Optimizer,
    args: Args,
    env_config: EnvConfig,
    update: int,
    frames: int,
) -> None:
    """A training run's checkpoint: weights, optimiser, counters, settings and config."""
    save_checkpoint(
        path,
        {
            "model": policy.state_dict(),
            "optimizer": optimizer.state_dict(),
            "agent": args.agent,
            "task": args.task,
            "env_config": env_config_to_dict(env_config),
            "args": asdict(args),
            "update": update,
            "frames": frames,
        },
    )


def _prepare(
    args: Args, evaluation: Evaluation | None
) -> tuple[EnvConfig, RecurrentPolicy, torch.optim.Optimizer, Placement]:
    """Checks that fail before anything starts, the device and DD-PPO rank, and the
    untrained policy (identical initial weights on every rank) with its optimiser."""
    if args.eval_episodes > 0 and evaluation is None:
        raise ValueError(
            f"eval_episodes is {args.eval_episodes} but no evaluation was passed to the run "
            "(multion train passes multion_agents.periodic_eval.ValEvaluation)"
        )
    device = select_device(args.device)
    rank, world = init_distributed(device)
    placement = Placement(
        device, rank, world, max(1, args.threads), args.update_threads or cores_per_rank()
    )
    torch.set_num_threads(placement.act_threads)
    env_config = run_env_config(args)
    check_curriculum(args.curriculum, env_config)
    check_map_pretraining(args.pretrain_map, args.agent, model_spec(args.agent).sensors)
    check_vision_pretraining(
        args.pretrain_vision, args.agent, model_spec(args.agent).sensors, args.pretrain_recogniser
    )
    torch.manual_seed(args.seed)
    policy = build_policy(
        args.agent,
        env_config,
        args.hidden_size,
        args.goal_heads,
        args.found_head > 0,
        args.pose_input,
        args.separate_critic,
        args.found_head_reads_image,
    ).to(device)
    for flag, asked in (
        ("--balanced-recognition", args.balanced_recognition),
        ("--pretrain-recogniser", args.pretrain_recogniser),
    ):
        if asked and not isinstance(policy.memory, ObjRecogMap):
            raise ConfigError(f"{flag} trains ObjRecogMap's recogniser; {args.agent} has none")
    if isinstance(policy.memory, ObjRecogMap):
        policy.memory.balanced = args.balanced_recognition
    if args.found_prior is not None:
        set_found_prior(policy, args.found_prior)
    optimizer = torch.optim.Adam(policy.parameters(), lr=args.learning_rate, eps=1e-5)
    return env_config, policy, optimizer, placement


def _agreement(rollout: Rollout) -> float:
    """The fraction of labelled steps where the learner took the expert's action (nan: none)."""
    labelled = rollout.expert_actions != NO_LABEL
    if not rollout.expert_actions.numel() or not labelled.any():
        return math.nan
    return float((rollout.actions[labelled] == rollout.expert_actions[labelled]).float().mean())
