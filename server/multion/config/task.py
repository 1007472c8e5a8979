"""Configs of the MultiON task: its rules, sensors and maps, the whole environment, and what a
generated episode must satisfy."""

from __future__ import annotations

from dataclasses import dataclass, field

from multion.config.ranges import ConfigError, bounded, check_fields, one_of, require
from multion.config.scenes import SPLITS
from multion.config.sensors import SENSORS as SENSORS  # re-exported: read here since before
from multion.config.sim import AgentConfig, CameraConfig, NavGridConfig
from multion_client.constants import DEFAULT_GOAL_SET, GOAL_SETS, NUM_CATEGORIES
from multion_client.semantic_map import MAP_CONVENTIONS, PROJECT_CONVENTION

TRAIN_SAMPLERS = ("sites", "online")
"""How train episodes are drawn (``EnvConfig.train_sampler``)."""
GOAL_SITES = 32
GOAL_SITE_CACHE_MIB = 800


@dataclass(frozen=True)
class EpisodeConstraints:
    """What a generated episode must satisfy (paper §5)."""

    min_geodesic: float = 2.0
    max_geodesic: float = 20.0
    min_goal_separation: float = 1.0
    """Euclidean metres between any two goals, so cylinders never overlap."""
    min_distractor_separation: float = 3.5
    """Euclidean metres from a distractor to every goal: more than twice the 1.5 m success
    distance, so a FOUND within reach of a distractor is never within reach of a goal (geodesic
    distances are at least the Euclidean ones)."""
    max_tries: int = 200
    mobile_start: bool = True
    """Refuse starts where no MOVE_FORWARD succeeds in any heading the agent can turn to (5 of
    the 8,000 episodes of the version 2 datasets started so). A quick test before ``step_paths``."""
    step_paths: bool = True
    """Refuse episodes where the agent's own moves (0.25 m steps, 30° turns) cannot bring it
    within ``reach`` of every goal (:func:`multion.task.step_reach.steps_reach_goals`): the grid
    can pass gaps no sequence of steps enters."""
    reach: float = 1.5
    """The task's success distance (``task.success_distance``) for ``step_paths``."""

    def __post_init__(self) -> None:
        if not 0 < self.min_geodesic <= self.max_geodesic:
            raise ConfigError(
                f"need 0 < min_geodesic <= max_geodesic, got {self.min_geodesic}, {self.max_geodesic}"
            )
        if self.min_goal_separation < 0 or self.min_distractor_separation < 0:
            raise ConfigError("goal and distractor separations must be >= 0")
        if self.reach <= 0:
            raise ConfigError(f"reach must be > 0, got {self.reach}")
        if self.max_tries < 1:
            raise ConfigError(f"max_tries must be >= 1, got {self.max_tries}")


@dataclass(frozen=True)
class MapConfig:
    """Oracle map and visibility settings."""

    cell_size: float = bounded(0.8, 0.05, 5.0)
    """Side of an oracle-map cell, metres (paper: 0.8)."""
    ego_size: int = bounded(50, 1, 1001)
    """Side of the egocentric crop, cells. 50 cells of 0.8 m (40 m × 40 m) is the reference
    code's oracle crop (``habitat/core/env.py`` lines 291-293; ``MapCNN(50, ...)`` in
    ``habitat_baselines/rl/ppo/policy.py`` lines 412, 419). For an even size the agent is in cell
    ``(ego_size // 2, ego_size // 2)``, as in the reference (module docstring). The default was 13
    until issue 31 (the reference's ``egocentric_map_size: 13`` is the learned maps'
    projection grid, not this crop); checkpoints record the size they were trained with."""
    goal_cells: int = bounded(3, 1, 15)
    """Side of the square of cells marking each goal object, cells (odd: the goal's cell in the
    middle). 3 is the reference's ``grid_loc ± 1`` (``habitat/core/env.py`` line 279); 1 marks
    the goal's cell alone (the default until issue 31)."""
    free_fraction: float = bounded(0.5, 0.0, 1.0)
    """A coarse cell is free when at least this fraction of its fine cells is navigable."""
    view_distance: float = bounded(5.0, 0.1, 50.0)
    """How far the agent sees, metres (supplement: 5 m)."""
    view_rays: int = bounded(80, 1, 1000)
    """Rays traced across the field of view to reveal the ego map."""
    convention: str = one_of(PROJECT_CONVENTION, MAP_CONVENTIONS)
    """How the crops are laid out: ``project`` (ahead up, the agent in the centre cell; what
    this project's agents and checkpoints read) or ``reference``, the reference code's
    ``semMap`` cell for cell (ahead down, and the ego map's seen cells + 1: see
    :mod:`multion.task.maps` and :mod:`multion_client.semantic_map`); habitat-style agents
    (``multion_client.habitat_compat``) ask for it."""

    def __post_init__(self) -> None:
        check_fields(self, "maps")
        require(self.goal_cells % 2 == 1, f"maps.goal_cells must be odd, got {self.goal_cells}")


@dataclass(frozen=True)
class TaskConfig:
    """Rules and rewards of MultiON (SPEC §2)."""

    num_goals: int = bounded(3, 1, NUM_CATEGORIES)
    """m, the number of ordered goals."""
    success_distance: float = bounded(1.5, 0.0, 20.0, low_open=True)
    """FOUND succeeds within this geodesic distance of the current goal, metres."""
    max_steps: int = bounded(2500, 1, 100_000)
    found_budget: int = bounded(0, 0, 100_000)
    """Wrong FOUNDs allowed before one ends the episode (0: the first one ends it)."""
    goal_reward: float = bounded(3.0, -1000.0, 1000.0)
    slack_reward: float = bounded(-0.01, -1000.0, 1000.0)
    wrong_found_penalty: float = bounded(0.0, -1000.0, 1000.0)
    """Subtracted from the reward of a wrong FOUND (the reference code's FALSE_FOUND_PENALTY,
    off in the paper's runs)."""
    goal_set: str = one_of(DEFAULT_GOAL_SET, tuple(GOAL_SETS))
    """Which goal objects are drawn: ``colours``, the paper's 8 coloured cylinders
    (``goal_radius``, ``goal_height``); ``shapes``, the supplement's 8 red shapes on thin
    supports (``shape_size``, ``shape_support_height``; names in
    ``multion_client.constants.SHAPE_CATEGORIES``); ``objects``, 8 everyday objects 0.35-0.9 m
    across from the models PyBullet ships, each at a yaw drawn from the episode id (MultiON 2.0's
    REAL-OBJECTS track, :mod:`multion.sim.goal_objects`); or ``unseen_train`` / ``unseen_test``,
    disjoint random shapes to train and test on. Category ids, FOUND, rewards, ``goal_mask`` and
    the oracle maps do not depend on it: the same episodes serve every set."""
    goal_radius: float = bounded(0.05, 0.01, 0.5)
    goal_height: float = bounded(0.75, 0.05, 3.0)
    shape_size: float = bounded(0.4, 0.05, 1.0)
    """Horizontal length or diameter of a shape goal, metres (supplement: 0.4)."""
    shape_support_height: float = bounded(0.6, 0.0, 2.0)
    """Height of a shape goal's support, metres: the shape sits on top of it."""
    goals_visible: bool = True
    """False leaves the goal cylinders out of the rendered world (the paper's hidden-objects
    ablation); they still count for FOUND, rewards and the oracle maps."""
    num_distractors: int = bounded(0, 0, NUM_CATEGORIES - 1)
    """Distractor cylinders per episode, of categories that are not among its goals (the MultiON
    2022 challenge's setting); valid range 0..8 - num_goals. 0 is the paper's task. They are drawn,
    in ``goal_mask`` and the oracle maps with their category + 1 like goals; a FOUND near one is a
    wrong FOUND (counted in ``distractor_founds``). Episodes come from the dataset, which must have
    this many distractors per episode (the packaged ``m-on-distractors`` sets have 3)."""
    train_sampler: str = one_of("sites", TRAIN_SAMPLERS)
    """How train episodes are drawn when no dataset is given. ``sites`` (the default since
    issue 44): every goal is one of ``goal_sites`` fixed, seeded sites of the house, whose
    distance fields are marched once and kept (:mod:`multion.task.goal_sites`), so a reset
    marches no field once a house's sites are cached. ``online``: start and goals anywhere on
    the floor, ``m + 1`` fields marched per episode (the sampler of every run published before
    issue 44; ``multion train --set task.train_sampler=online`` reproduces them). Both keep the
    same constraints."""
    goal_sites: int = bounded(GOAL_SITES, 16, 1024)
    """Goal sites per train house (``train_sampler = "sites"``): one in every room (a house has
    at most 16), the rest spread over the floor."""
    goal_site_cache_mib: int = bounded(GOAL_SITE_CACHE_MIB, 1, 65_536)
    """Memory for the goal sites' distance fields, MiB per process: every env of a process
    reads one cache (:class:`multion.task.goal_sites.SiteFieldCache`), bounded by the largest
    value its envs give; the least recently used fields are dropped, and marched again when
    drawn (the same episodes either way). The default holds every field of the 61 train houses
    at 32 sites a house (1,952 fields, 766 MiB measured); a server reserves it once per worker
    process holding train sessions that draw from sites."""

    def __post_init__(self) -> None:
        check_fields(self, "task")


@dataclass(frozen=True)
class EnvConfig:
    """Everything that defines a MultiON environment."""

    task: TaskConfig = field(default_factory=TaskConfig)
    agent: AgentConfig = field(default_factory=AgentConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    navgrid: NavGridConfig = field(default_factory=NavGridConfig)
    maps: MapConfig = field(default_factory=MapConfig)
    sensors: tuple[str, ...] = ("rgb", "depth", "goal")
    split: str = one_of("val", SPLITS)
    """Which scenes and packaged episodes: train (sampled online), val or test."""
    dataset: str | None = None
    """A dataset file; None uses the packaged one for (m, split), or samples online for train."""
    episodes_per_scene: int = bounded(25, 1, 1_000_000)
    """Online (train) sampling draws this many episodes in a scene before moving to another:
    a scene switch rebuilds the PyBullet world, and early training episodes are a few steps."""
    online_max_geodesic: float = bounded(
        EpisodeConstraints.max_geodesic,
        EpisodeConstraints.min_geodesic,
        EpisodeConstraints.max_geodesic,
    )
    """Online (train) sampling keeps each goal within this geodesic distance, metres, of the
    start or the previous goal; below the datasets' 20 m it makes a curriculum's easy stage
    (``multion train --curriculum``). Packaged and file datasets ignore it."""

    def __post_init__(self) -> None:
        check_fields(self, "")
        unknown = [s for s in self.sensors if s not in SENSORS]
        require(not unknown, f"unknown sensor(s) {unknown}; known sensors: {list(SENSORS)}")
        repeated = sorted({s for s in self.sensors if self.sensors.count(s) > 1})
        require(not repeated, f"sensor(s) {repeated} named more than once in sensors")
        require(
            self.task.num_goals + self.task.num_distractors <= NUM_CATEGORIES,
            f"task.num_distractors must be in 0..{NUM_CATEGORIES - self.task.num_goals} with "
            f"{self.task.num_goals} goals (categories are not shared), "
            f"got {self.task.num_distractors}",
        )
