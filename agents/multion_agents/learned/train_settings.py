"""The settings of a training run (``Args``): each field's default, range and ``multion train``
option in one place (``multion_agents.cli_fields``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from multion.config.datasets import parse_task
from multion.config.ranges import ConfigError
from multion_agents.agent import ConfigOverrides
from multion_agents.cli_fields import Option, check_settings, setting
from multion_agents.config_overrides import parse_env_overrides
from multion_agents.learned.policy import HIDDEN_SIZE, MAX_HIDDEN_SIZE
from multion_agents.learned.precision import PRECISIONS
from multion_agents.learned.train_options import (
    EXPERTS,
    FOUND_HEAD_LABELS,
    Curriculum,
    FoundCurriculum,
    MapPretraining,
    VisionPretraining,
    parse_curriculum,
    parse_found_curriculum,
)

PPO = "PPO schedule (defaults follow the reference code, ppo_multinav.yaml)"


def _task_name(text: str) -> str:
    parse_task(text)  # a ValueError naming the known tasks
    return text


def _pretraining(steps: int) -> MapPretraining:
    try:
        return MapPretraining(steps=steps)
    except ValueError as error:
        raise ConfigError(f"--pretrain-map: {error}") from None


def _vision_pretraining(steps: int) -> VisionPretraining:
    try:
        return VisionPretraining(steps=steps)
    except ValueError as error:
        raise ConfigError(f"--pretrain-vision: {error}") from None


BEYOND_PAPER = "beyond the paper's recipe (each off by default; issue 51, docs/learn-to-see.md)"


@dataclass(frozen=True)
class Args:
    """A training run. Defaults are the reference configuration's PPO (saimwani/multiON,
    ``ppo_multinav.yaml``; SPEC §6): 16 environments, learning rate and clip range decayed
    linearly to zero over the run, advantages not normalised. docs/learned.md lists what still
    differs from the paper."""

    agent: str = setting("oracle-map", cli=Option("model name (see --list)"))
    """Model name, one of ``multion_agents.learned.models.MODELS``."""
    task: str = setting("1-on", cli=Option("1-on … 8-on (default 1-on)", parse=_task_name))
    frames: int = setting(1_000_000, low=1, cli=Option("environment steps, all ranks together"))
    """Environment steps to train for, summed over all ranks."""
    envs: int = setting(
        16, low=1, cli=Option("environments per rank (default %(default)s, the paper's)")
    )
    envs_per_process: int = setting(
        1,
        low=1,
        high=64,
        cli=Option(
            "local environments per simulator process, stepped in turn (1-64; default 1: one "
            "process each); more share a process's goal-site cache and scenes, using less memory"
        ),
    )
    servers: tuple[str, ...] = setting(
        (),
        cli=Option(
            "step environments on this server URL (repeatable); default: local simulator processes",
            flag="--server",
            metavar="SERVER",
            repeat=True,
            parse=tuple,
        ),
    )
    image_size: int = setting(256, low=1, cli=Option("camera width = height (paper 256)"))
    hidden_size: int = setting(
        HIDDEN_SIZE,
        low=1,
        high=MAX_HIDDEN_SIZE,
        cli=Option(f"GRU units, 1-{MAX_HIDDEN_SIZE} (default %(default)s, the reference's)"),
    )
    seed: int = setting(1, cli=Option("seed of the policy, the environments and the episodes"))
    out: str = setting(
        "runs/train",
        cli=Option(
            "run directory (checkpoint.pt, progress.csv, eval.csv, tensorboard/, "
            "learning_curve.png)"
        ),
    )
    resume: bool = setting(False, cli=Option("continue from OUT/checkpoint.pt"))
    checkpoint_every: int = setting(10, low=1, cli=Option("updates between checkpoints"))
    """Save a checkpoint every N updates (and at the end)."""
    eval_every: int = setting(
        0, low=0, cli=Option("frames between val evaluations (0: only at the end)")
    )
    eval_episodes: int = setting(0, low=0, cli=Option("val episodes per evaluation (0: none)"))
    """Val episodes per evaluation (evenly spaced over the packaged val set)."""
    max_steps: int | None = setting(
        None,
        low=1,
        integer=True,
        cli=Option("step limit of training episodes (default: the task's 2500)"),
    )
    """Step limit of *training* episodes; evaluation always uses 2500."""
    env_overrides: ConfigOverrides = setting(
        default_factory=dict,
        cli=Option(
            "change the training env config, e.g. --set task.wrong_found_penalty=2.5 "
            "--set maps.ego_size=25 (repeatable; values are JSON or strings)",
            flag="--set",
            metavar="SECTION.FIELD=VALUE",
            repeat=True,
            parse=parse_env_overrides,
        ),
    )
    dataset: str | None = setting(
        None,
        cli=Option(
            "train on this dataset file's episodes (default: sample train-split episodes online)"
        ),
    )
    found_prior: float | None = setting(
        None,
        cli=Option("initial probability of FOUND (default: uniform, 0.25, as in the paper)"),
    )
    """A small value keeps the untrained policy from ending most episodes by a wrong FOUND in
    its first steps, which otherwise teaches it early that FOUND ends the slack penalty (see
    docs/learned.md). Its range, (0, 1), is checked by ``ppo.set_found_prior``."""
    episodes_per_scene: int = setting(
        25, low=1, cli=Option("online episodes sampled in one scene before the next scene")
    )
    pretrain_map: MapPretraining = setting(
        default_factory=MapPretraining,
        cli=Option(
            "before PPO, train STEPS supervised steps on oracle-map crops at random poses "
            "(0-20000; agents that read oracle_map; default 0, none, as in the paper; the v3 "
            "recipe uses 1200, see docs/learned.md)",
            metavar="STEPS",
            kind=int,
            parse=_pretraining,
        ),
    )
    """``learned/pretrain.py``; skipped on ``resume`` (the checkpoint holds it)."""
    curriculum: Curriculum = setting(
        (),
        cli=Option(
            "easier episodes first: until FRAMES frames, online episodes keep each goal within "
            "METRES (2-20) of the start or the previous goal (repeatable, increasing FRAMES; "
            "e.g. --curriculum 240000:4 --curriculum 480000:10)",
            metavar="FRAMES:METRES",
            repeat=True,
            parse=parse_curriculum,
        ),
    )
    """Each stage starts fresh environments and episodes (``rollout_envs.stage_config``)."""
    found_curriculum: FoundCurriculum = setting(
        default_factory=FoundCurriculum,
        cli=Option(
            "until FRAMES frames, a wrong FOUND costs PENALTY but does not end the training "
            "episode; then the task's rule (e.g. 200000:2.5; default off)",
            metavar="FRAMES:PENALTY",
            parse=parse_found_curriculum,
            group=BEYOND_PAPER,
        ),
    )
    """Switching starts fresh environments and episodes, as a curriculum stage does."""
    goal_heads: bool = setting(
        False,
        cli=Option(
            "auxiliary heads on the GRU state: has the goal been seen, its direction and "
            "distance (Marza et al. 2022), trained from the goal_vector sensor, dropped at "
            "evaluation",
            toggle=True,
            group=BEYOND_PAPER,
        ),
    )
    pose_input: bool = setting(
        False,
        cli=Option(
            "the GRU also reads GPS and compass (the pose from the episode's start), each "
            "embedded to 32 units as in habitat-lab's ObjectNav baseline; kept at evaluation",
            toggle=True,
            group=BEYOND_PAPER,
        ),
    )
    separate_critic: bool = setting(
        False,
        cli=Option(
            "the critic reads its own GRU over the same inputs, detached, so the value loss "
            "no longer trains the encoder or the actor's GRU (separate networks avoid "
            "interference: Cobbe et al. 2021, Phasic Policy Gradient); dropped at evaluation",
            toggle=True,
            group=BEYOND_PAPER,
        ),
    )
    goal_head_coef: float = setting(
        0.25,
        low=0,
        cli=Option(
            "weight of each goal head's loss (default %(default)s, Marza et al.'s)",
            group=BEYOND_PAPER,
        ),
    )
    found_supervision: float = setting(
        0.0,
        low=0,
        high=10,
        cli=Option(
            "weight of a class-balanced cross-entropy teaching P(FOUND) where FOUND would "
            "succeed, from the goal_distance oracle that only training receives, in [0, 10] "
            "(default 0: off, as in the paper)",
            group=BEYOND_PAPER,
        ),
    )
    found_head: float = setting(
        0.0,
        low=0,
        high=10,
        cli=Option(
            "weight of the cross-entropy of a FOUND head that alone decides FOUND (the policy "
            "calls it where the head's probability exceeds 0.5, and PPO teaches only the "
            "movements), trained where FOUND would succeed with the goal in view, from the "
            "goal_distance and goal_mask oracles that only training receives, in [0, 10] "
            "(default 0: off, FOUND is one of the actor's actions as in the paper)",
            group=BEYOND_PAPER,
        ),
    )
    """Not with ``--found-supervision``, which teaches the actor's own FOUND."""
    found_head_reads_image: bool = setting(
        False,
        cli=Option(
            "the FOUND head reads the current frame's image embedding beside the GRU output, "
            "so a map filling the GRU's input does not stand between the frame and FOUND; "
            "kept at evaluation; needs --found-head",
            toggle=True,
            group=BEYOND_PAPER,
        ),
    )
    found_head_label: str = setting(
        "in-view",
        choices=FOUND_HEAD_LABELS,
        cli=Option(
            "where the FOUND head learns that FOUND would succeed: in-view, within the success "
            "distance with the goal in the frame; seen, within it with the goal in view at any "
            "step of the episode so far (goal_vector's flag), which a memory can know standing "
            "on a goal the frame no longer shows (default %(default)s); needs --found-head",
            group=BEYOND_PAPER,
        ),
    )
    found_head_positive_weight: float = setting(
        1.0,
        low=1,
        high=1000,
        cli=Option(
            "weight of the FOUND head's positive steps (FOUND would succeed, goal in view) in "
            "its PPO-time cross-entropy, in [1, 1000] (default 1: unweighted); they are 0.2-0.6 "
            "%% of steps, and unweighted the head fires on few of them",
            group=BEYOND_PAPER,
        ),
    )
    coverage_reward: float = setting(
        0.0,
        low=0,
        high=10,
        cli=Option(
            "exploration bonus R added to the task's reward while training: R x 0.995^t / n at "
            "step t, n the steps spent so far in the agent's 2.5 m cell (Ye et al. 2021), "
            "in [0, 10] (default 0: none, as in the paper); needs local environments",
            group=BEYOND_PAPER,
        ),
    )
    """``learned/coverage.py``."""
    pretrain_vision: VisionPretraining = setting(
        default_factory=VisionPretraining,
        cli=Option(
            "before PPO, train the image encoder STEPS supervised steps to tell which goal "
            "objects are in view and where, on rendered frames labelled by goal_mask, half of "
            "them showing a goal (0-50000; default 0, none)",
            metavar="STEPS",
            kind=int,
            parse=_vision_pretraining,
            group=BEYOND_PAPER,
        ),
    )
    """``learned/vision_pretrain.py``; skipped on ``resume`` (the checkpoint holds it)."""
    balanced_recognition: bool = setting(
        False,
        cli=Option(
            "weigh ObjRecogMap's recogniser classes equally in each batch (most frames show "
            "no goal)",
            toggle=True,
            group=BEYOND_PAPER,
        ),
    )
    pretrain_recogniser: bool = setting(
        False,
        cli=Option(
            "with --pretrain-vision, ObjRecogMap's recogniser learns on the same rendered "
            "frames, class-balanced, before PPO",
            toggle=True,
            group=BEYOND_PAPER,
        ),
    )
    """``learned/vision_pretrain.py`` (``RecogniserPretraining``): the recogniser that learned
    only during PPO answered on 42 % of the val frames showing the goal within 1.5 m, where a
    linear probe of the same image embedding answered on 86 % (docs/learn-to-see.md)."""
    freeze_vision: bool = setting(
        False,
        cli=Option(
            "with --pretrain-vision, PPO leaves the image encoder as pretraining left it, so "
            "the features a learned map writes stay the same all run",
            toggle=True,
            group=BEYOND_PAPER,
        ),
    )
    """``learned/vision_pretrain.py`` (``freeze_image_encoder``): with the encoder trained by PPO,
    what ProjNeuralMap and ObjRecogMap write changes under the map as the run goes. It also
    makes the update cheaper: the rollout keeps the encoder's outputs and the update replays them
    (``multion bench --only learner --learner-freeze-vision``; docs/training-speed.md)."""
    threads: int = setting(
        1,
        low=1,
        cli=Option("torch threads per rank (default 1: fastest when simulators share the cores)"),
    )
    """With more, OpenMP threads spin against the simulators (20× slower steps measured on 2
    cores)."""
    update_threads: int = setting(
        0,
        low=0,
        cli=Option(
            "torch threads for PPO updates, while simulators wait (default 0: this rank's cores)"
        ),
    )
    device: str = setting("auto", cli=Option("cpu, cuda, cuda:N or auto (cuda when available)"))
    mixed_precision: str = setting(
        "off",
        choices=PRECISIONS,
        cli=Option(
            "PPO update in mixed precision: off (default, float32), bf16 (autocast) or fp16 "
            "(autocast and loss scaling, CUDA only); for GPUs, slower on a CPU"
        ),
    )
    lr_decay: bool = setting(
        True,
        cli=Option("decay the learning rate linearly to 0 over the run", toggle=True, group=PPO),
    )
    clip_decay: bool = setting(
        True,
        cli=Option(
            "decay the PPO clip range (policy and value) linearly to 0 over the run",
            toggle=True,
            group=PPO,
        ),
    )
    normalize_advantages: bool = setting(
        False, cli=Option("normalise advantages per rollout", toggle=True, group=PPO)
    )
    """The reference: use_normalized_advantage False; this trainer's earlier default was True."""
    tensorboard: bool = setting(
        True, cli=Option("write no TensorBoard logs", flag="--no-tensorboard", negate=True)
    )
    progress: bool = setting(True, cli=Option("no progress bar", flag="--quiet", negate=True))
    rollout_steps: int = setting(
        128, low=1, cli=Option("steps per environment between updates (default %(default)s)")
    )
    learning_rate: float = setting(
        2.5e-4, low=0, low_open=True, cli=Option("Adam learning rate (default %(default)s)")
    )
    clip: float = setting(
        0.2, low=0, low_open=True, cli=Option("PPO clip range (default %(default)s)")
    )
    epochs: int = setting(2, low=1, cli=Option("PPO epochs per update (default %(default)s)"))
    minibatches: int = setting(
        4, low=1, cli=Option("recurrent mini-batches per epoch (≤ envs) (default %(default)s)")
    )
    value_coef: float = setting(0.5, low=0, cli=Option("value loss weight (default %(default)s)"))
    entropy_coef: float = setting(
        0.01, low=0, cli=Option("entropy bonus weight (default %(default)s)")
    )
    aux_coef: float = setting(
        1.0, low=0, cli=Option("auxiliary loss weight (ObjRecogMap) (default %(default)s)")
    )
    imitation_coef: float = setting(
        0.0,
        low=0,
        high=100,
        cli=Option(
            "weight of the cross-entropy to oracle-planner's actions on the learner's states, "
            "in [0, 100] (0: pure PPO, as in the paper) (default %(default)s)"
        ),
    )
    """The learner stays in control (DAgger's labels, ``learned/expert.py``); needs local
    environments."""
    expert: str = setting(
        "oracle-planner",
        choices=EXPERTS,
        cli=Option(
            "who labels the learner's states for --imitation-coef: oracle-planner (plans on an "
            "oracle map) or explorer (frontier exploration from the learner's own sensors) "
            "(default %(default)s)"
        ),
    )
    max_grad_norm: float = setting(
        0.2, low=0, low_open=True, cli=Option("gradient clipping norm (default %(default)s)")
    )
    gamma: float = setting(0.99, low=0, high=1, cli=Option("discount (default %(default)s)"))
    gae_lambda: float = setting(0.95, low=0, high=1, cli=Option("GAE lambda (default %(default)s)"))
    extra: dict[str, Any] = setting(default_factory=dict)
    """Free-form notes stored in the checkpoint (e.g. the command line)."""

    def __post_init__(self) -> None:
        check_settings(self)
        if self.found_head_positive_weight != 1 and self.found_head == 0:
            raise ConfigError(
                "--found-head-positive-weight weighs the FOUND head's loss: it needs --found-head"
            )
        if self.freeze_vision and self.pretrain_vision.steps == 0:
            raise ConfigError(
                "--freeze-vision keeps what --pretrain-vision STEPS taught the image encoder: "
                "it needs --pretrain-vision"
            )
        if self.found_head_label != "in-view" and self.found_head == 0:
            raise ConfigError("--found-head-label labels the FOUND head: it needs --found-head")
        if self.found_head_reads_image and self.found_head == 0:
            raise ConfigError(
                "--found-head-reads-image widens the FOUND head: it needs --found-head"
            )
        if self.expert != "oracle-planner" and self.imitation_coef == 0:
            raise ConfigError(
                f"--expert {self.expert} labels the learner's states for the imitation loss: it "
                "needs --imitation-coef above 0"
            )
        if self.found_head > 0 and self.found_supervision > 0:
            raise ConfigError(
                "--found-head and --found-supervision: pick one (the head decides FOUND, "
                "the supervision teaches the actor's FOUND)"
            )
