"""``multion train``: train a learned agent with PPO, or DD-PPO under ``torchrun``.

Examples::

    multion train --agent oracle-map --task 1-on --frames 2000000 --envs 4 --out runs/om
    multion train --agent oracle-map --task 1-on --frames 2000000 --out runs/om --resume
    multion train --agent no-map --server http://gpu-box:8000 --server http://gpu-box:8001 --envs 8
    torchrun --nproc-per-node 2 -m multion_agents.cli train --agent oracle-map --envs 2 --out runs/ddppo

Every rank of a ``torchrun`` job steps ``--envs`` environments of its own; only rank 0 writes
logs and checkpoints.
"""

from __future__ import annotations

import argparse
import sys

_HYPER = (
    ("rollout-steps", int, "steps per environment between updates"),
    ("learning-rate", float, "Adam learning rate"),
    ("clip", float, "PPO clip range"),
    ("epochs", int, "PPO epochs per update"),
    ("minibatches", int, "recurrent mini-batches per epoch (≤ envs)"),
    ("value-coef", float, "value loss weight"),
    ("entropy-coef", float, "entropy bonus weight"),
    ("aux-coef", float, "auxiliary loss weight (ObjRecogMap)"),
    (
        "imitation-coef",
        float,
        "weight of the cross-entropy to oracle-planner's actions on the "
        "learner's states, in [0, 100] (0: pure PPO, as in the paper)",
    ),
    ("max-grad-norm", float, "gradient clipping norm"),
    ("gamma", float, "discount"),
    ("gae-lambda", float, "GAE lambda"),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from multion_agents.learned.ppo import Args

    defaults = Args()
    parser.add_argument("--agent", default=defaults.agent, help="model name (see --list)")
    parser.add_argument("--list", action="store_true", help="list the learned agents and exit")
    parser.add_argument("--task", default=defaults.task, help="1-on … 8-on (default 1-on)")
    parser.add_argument(
        "--frames", type=int, default=defaults.frames, help="environment steps, all ranks together"
    )
    parser.add_argument(
        "--envs",
        type=int,
        default=defaults.envs,
        help=f"environments per rank (default {defaults.envs}, the paper's)",
    )
    parser.add_argument(
        "--server",
        action="append",
        default=[],
        help="step environments on this server URL (repeatable); default: local simulator processes",
    )
    parser.add_argument(
        "--image-size",
        type=int,
        default=defaults.image_size,
        help="camera width = height (paper 256)",
    )
    parser.add_argument(
        "--hidden-size",
        type=int,
        default=defaults.hidden_size,
        help=f"GRU units, 1-4096 (default {defaults.hidden_size}, the reference's)",
    )
    parser.add_argument("--seed", type=int, default=defaults.seed)
    parser.add_argument(
        "--out",
        default=defaults.out,
        help="run directory (checkpoint.pt, progress.csv, eval.csv, tensorboard/, learning_curve.png)",
    )
    parser.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.pt")
    parser.add_argument(
        "--checkpoint-every",
        type=int,
        default=defaults.checkpoint_every,
        help="updates between checkpoints",
    )
    parser.add_argument(
        "--eval-every",
        type=int,
        default=defaults.eval_every,
        help="frames between val evaluations (0: only at the end)",
    )
    parser.add_argument(
        "--eval-episodes",
        type=int,
        default=defaults.eval_episodes,
        help="val episodes per evaluation (0: none)",
    )
    parser.add_argument(
        "--max-steps",
        type=int,
        default=None,
        help="step limit of training episodes (default: the task's 2500)",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SECTION.FIELD=VALUE",
        help="change the training env config, e.g. --set task.wrong_found_penalty=2.5 "
        "--set maps.ego_size=25 (repeatable; values are JSON or strings)",
    )
    parser.add_argument(
        "--dataset",
        default=None,
        help="train on this dataset file's episodes (default: sample train-split episodes online)",
    )
    parser.add_argument(
        "--found-prior",
        type=float,
        default=None,
        help="initial probability of FOUND (default: uniform, 0.25, as in the paper)",
    )
    parser.add_argument("--episodes-per-scene", type=int, default=defaults.episodes_per_scene)
    parser.add_argument(
        "--pretrain-map",
        type=int,
        default=defaults.pretrain_map.steps,
        metavar="STEPS",
        help="before PPO, train STEPS supervised steps on oracle-map crops at random poses "
        "(0-20000; agents that read oracle_map; default 0, none, as in the paper; the v3 "
        "recipe uses 1200, see docs/learned.md)",
    )
    parser.add_argument(
        "--curriculum",
        action="append",
        default=[],
        metavar="FRAMES:METRES",
        help="easier episodes first: until FRAMES frames, online episodes keep each goal within "
        "METRES (2-20) of the start or the previous goal (repeatable, increasing FRAMES; "
        "e.g. --curriculum 240000:4 --curriculum 480000:10)",
    )
    parser.add_argument(
        "--threads",
        type=int,
        default=defaults.threads,
        help="torch threads per rank (default 1: fastest when simulators share the cores)",
    )
    parser.add_argument(
        "--update-threads",
        type=int,
        default=defaults.update_threads,
        help="torch threads for PPO updates, while simulators wait (default 0: this rank's cores)",
    )
    parser.add_argument(
        "--device", default="auto", help="cpu, cuda, cuda:N or auto (cuda when available)"
    )
    reference = parser.add_argument_group(
        "PPO schedule (defaults follow the reference code, ppo_multinav.yaml)"
    )
    reference.add_argument(
        "--lr-decay",
        action=argparse.BooleanOptionalAction,
        default=defaults.lr_decay,
        help="decay the learning rate linearly to 0 over the run",
    )
    reference.add_argument(
        "--clip-decay",
        action=argparse.BooleanOptionalAction,
        default=defaults.clip_decay,
        help="decay the PPO clip range linearly to 0 over the run",
    )
    reference.add_argument(
        "--normalize-advantages",
        action=argparse.BooleanOptionalAction,
        default=defaults.normalize_advantages,
        help="normalise advantages per rollout",
    )
    parser.add_argument("--no-tensorboard", action="store_true")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    for name, kind, text in _HYPER:
        default = getattr(defaults, name.replace("-", "_"))
        parser.add_argument(
            f"--{name}", type=kind, default=default, help=f"{text} (default {default})"
        )


def run(args: argparse.Namespace) -> int:
    from multion.task.dataset import parse_task
    from multion_agents.config_overrides import parse_env_overrides
    from multion_agents.learned.checkpoint import CheckpointError
    from multion_agents.learned.models import MODELS
    from multion_agents.learned.ppo import Args, train
    from multion_agents.learned.pretrain import MapPretraining
    from multion_agents.learned.rollout_envs import parse_curriculum

    if args.list:
        for name, spec in MODELS.items():
            print(f"{name:28s} {spec.paper_name}")
        return 0
    try:
        parse_task(args.task)
    except ValueError as error:
        return _fail(str(error))
    if args.agent not in MODELS:
        return _fail(f"unknown learned agent {args.agent!r}; known: {', '.join(MODELS)}")
    for name in (
        "frames",
        "envs",
        "image_size",
        "rollout_steps",
        "epochs",
        "minibatches",
        "checkpoint_every",
    ):
        if getattr(args, name) <= 0:
            return _fail(f"--{name.replace('_', '-')} must be positive, got {getattr(args, name)}")
    try:
        env_overrides = parse_env_overrides(args.set)
        curriculum = parse_curriculum(args.curriculum)
    except ValueError as error:
        return _fail(str(error))
    try:
        pretraining = MapPretraining(steps=args.pretrain_map)
    except ValueError as error:
        return _fail(f"--pretrain-map: {error}")
    settings = Args(
        agent=args.agent,
        task=args.task,
        frames=args.frames,
        envs=args.envs,
        servers=tuple(args.server),
        image_size=args.image_size,
        hidden_size=args.hidden_size,
        seed=args.seed,
        out=args.out,
        resume=args.resume,
        checkpoint_every=args.checkpoint_every,
        eval_every=args.eval_every,
        eval_episodes=args.eval_episodes,
        max_steps=args.max_steps,
        episodes_per_scene=args.episodes_per_scene,
        curriculum=curriculum,
        found_prior=args.found_prior,
        pretrain_map=pretraining,
        dataset=args.dataset,
        env_overrides=env_overrides,
        threads=args.threads,
        update_threads=args.update_threads,
        device=args.device,
        lr_decay=args.lr_decay,
        clip_decay=args.clip_decay,
        normalize_advantages=args.normalize_advantages,
        tensorboard=not args.no_tensorboard,
        progress=not args.quiet,
        extra={"argv": sys.argv},
        **{name.replace("-", "_"): getattr(args, name.replace("-", "_")) for name, _, _ in _HYPER},
    )
    try:
        summary = train(settings)
    except (CheckpointError, ValueError) as error:
        return _fail(str(error))
    if summary:
        print(
            f"trained {args.agent} on {args.task}: {summary['frames']} frames, "
            f"{summary['fps']:.0f} frames/s in the last update; run directory {args.out}"
        )
    return 0


def _fail(message: str) -> int:
    print(f"multion train: {message}", file=sys.stderr)
    return 2
