"""The MultiON task as a Gymnasium environment."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from multion.config.datasets import load_dataset, packaged_dataset_path, variant_name
from multion.config.episode import Episode
from multion.config.sensors import GOAL_VECTOR_SEEN_DISTANCE
from multion.config.task import EnvConfig, EpisodeConstraints, TaskConfig
from multion.scenes.registry import SceneIdError, scene_ids
from multion.sim.geodesic import FieldCache, distance_field
from multion.sim.goal_objects import OBJECT_GOAL_SETS, goal_yaw
from multion.sim.navgrid import NavGrid
from multion.sim.simulator import Simulator
from multion.sim.world import MeshSceneError
from multion.task.episode_checks import (
    check_caller_episode,
    check_caller_episodes,
    check_reset_options,
)
from multion.task.errors import (
    BadEpisodeError,
    BadResetOptionError,
    DatasetError,
    EpisodeNotFoundError,
    EpisodeOverError,
    IllegalActionError,
)
from multion.task.goal_sites import GoalSites, sample_site_episode
from multion.task.maps import EgoMapReveal, OracleMap, PoseCrops, can_see
from multion.task.measures import EpisodeState, Measures
from multion.task.sampling import check_on_grid, sample_episode
from multion.task.sensors import Frame, SensorInputs, configured_sensors, uses_source
from multion.task.spaces import build_observation_space
from multion_client.constants import (
    ACTIONS_TEXT,
    GOAL_RGBA,
    NUM_ACTIONS,
    SHAPE_RGBA,
    Action,
    action_id,
    goal_categories,
)
from multion_client.protocol import MAX_SEED


class MultiONEnv(gym.Env[dict[str, np.ndarray], int]):
    """Multi-object navigation in a 3D home (MultiON, NeurIPS 2020).

    ## Description
    The agent must find an episode-specific, ordered list of ``m`` coloured cylinders and call
    FOUND within 1.5 m (geodesic) of each in turn.

    ## Observation
    A dict with the configured sensors: ``rgb`` (H, W, 3) uint8; ``depth`` (H, W, 1) float32 in
    [0, 1] (0–10 m by default); ``goal`` current goal category (0..7, of ``task.goal_set``);
    ``goal_onehot`` (8,); ``gps`` (2,)
    position relative to the start, in the start frame (x ahead, y left); ``compass`` (1,)
    heading relative to the start, radians; ``oracle_map`` / ``oracle_ego_map`` (S, S, 2) uint8
    egocentric crops (occupancy, goal category + 1 on a 3 × 3 square per goal; S = 50 by
    default); ``goal_mask`` (H, W) uint8, goal category + 1
    per pixel (for supervising recognisers). Distractors (``task.num_distractors``) appear in
    ``goal_mask`` and the oracle maps with their category + 1 too: their categories are never the
    episode's goals', so a recogniser learns categories and the current goal says which one counts; ``goal_distance`` (1,) oracle geodesic distance to the
    current goal (for oracle baselines such as Rand+OracleFound).

    ## Actions
    ``Discrete(4)``: 0 FOUND, 1 MOVE_FORWARD (0.25 m), 2 TURN_LEFT (30°), 3 TURN_RIGHT (30°).

    ## Rewards
    ``-0.01 + (d_{t-1} - d_t) + 3·[correct FOUND]``, d the geodesic distance to the current goal.

    ## Termination
    Terminated when every goal is found (success) or on a wrong FOUND beyond the found budget;
    truncated after ``max_steps`` actions. ``info["metrics"]`` always holds the episode's measures.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        config: EnvConfig | None = None,
        episodes: Sequence[Episode] | None = None,
        render_mode: str | None = None,
    ) -> None:
        self.config = config or EnvConfig()
        self.render_mode = render_mode
        self.sim = Simulator(self.config.agent, self.config.camera, self.config.navgrid)
        if episodes is not None:  # the caller's: checked here, a dataset's when it is read
            check_caller_episodes(episodes, self.config.task, "episodes")
        self.episodes = list(episodes) if episodes is not None else self._default_episodes()
        self._cursor = 0
        self._train_scenes = scene_ids("train") if self.episodes is None else []
        # gymnasium types a Dict space's elements as dicts of spaces (they are dicts of arrays)
        # and a Discrete space's as numpy integers (the actions this env takes are ints)
        self.observation_space = cast(
            spaces.Space[dict[str, np.ndarray]], build_observation_space(self.config)
        )
        self.action_space = cast(spaces.Space[int], spaces.Discrete(NUM_ACTIONS))
        self.episode: Episode | None = None
        self.state: EpisodeState | None = None
        self.measures = Measures()
        self._fields: list[np.ndarray] = []
        self._field_cache = FieldCache()
        self._distractor_fields: dict[int, np.ndarray] = {}
        self._oracle: OracleMap | None = None
        self._reveal: EgoMapReveal | None = None
        self._last_rgb: np.ndarray | None = None
        self._done = True
        self._online_count = 0
        self._online_scene: str | None = None
        self._online_constraints = EpisodeConstraints(
            max_geodesic=self.config.online_max_geodesic,
            reach=self.config.task.success_distance,
        )
        self._goal_sites: GoalSites | None = None
        """Its view of the process's goal-site cache, made at its first episode from sites."""
        self._tracks_goal_pose = uses_source(configured_sensors(self.config), "goal_pose")
        self._goals_seen: list[bool] = []
        """Per goal, whether it has been within ``GOAL_VECTOR_SEEN_DISTANCE`` in view (kept only
        for ``goal_vector``)."""

    # ------------------------------------------------------------------ episodes
    def _default_episodes(self) -> list[Episode] | None:
        cfg = self.config
        task = cfg.task
        if cfg.dataset is not None:
            return load_dataset(cfg.dataset, task.num_goals, task.num_distractors)
        path = packaged_dataset_path(task.num_goals, cfg.split, task.num_distractors)
        if path.is_file():
            return load_dataset(path, task.num_goals, task.num_distractors)
        if cfg.split == "train":
            return None  # sampled online from the train scenes
        raise DatasetError(
            f"no packaged {variant_name(task.num_goals, task.num_distractors)} {cfg.split} "
            "dataset; "
            f"generate one with `multion dataset generate` and pass it as `dataset`"
        )

    def _next_episode(self, options: dict[str, Any]) -> Episode:
        if "episode" in options:
            episode = options["episode"]
            if not isinstance(episode, Episode):
                try:
                    episode = Episode.from_dict(episode, "options.episode")
                except ValueError as error:  # from_dict's ConfigError, naming the field
                    raise BadEpisodeError(f"malformed inline episode: {error}") from None
            check_caller_episode(episode, self.config.task, "options.episode")
            return episode
        if self.episodes is None:
            if (
                self._online_scene is None
                or self._online_count % self.config.episodes_per_scene == 0
            ):
                index = int(self.np_random.integers(len(self._train_scenes)))
                self._online_scene = self._train_scenes[index]
            scene = self._online_scene
            grid = self.sim.load_scene(scene)
            self._online_count += 1
            if self.config.task.train_sampler == "online":
                episode = sample_episode(
                    grid,
                    scene,
                    self.config.task.num_goals,
                    self.np_random,
                    f"train-online-{self._online_count:07d}",
                    num_distractors=self.config.task.num_distractors,
                    constraints=self._online_constraints,
                    fields=self._field_cache,
                )
            else:
                if self._goal_sites is None:
                    task = self.config.task
                    budget = task.goal_site_cache_mib * 2**20
                    self._goal_sites = GoalSites(task.goal_sites, task.goal_radius, budget)
                episode = sample_site_episode(
                    self._goal_sites,
                    grid,
                    scene,
                    self.config.task.num_goals,
                    self.np_random,
                    f"train-sites-{self._online_count:07d}",
                    num_distractors=self.config.task.num_distractors,
                    constraints=self._online_constraints,
                    fields=self._field_cache,
                )
            if episode is None:  # no valid episode found here: try another scene
                self._online_scene = None
                return self._next_episode(options)
            return episode
        if "episode_index" in options:
            index = int(options["episode_index"])
            if not 0 <= index < len(self.episodes):
                raise EpisodeNotFoundError(
                    f"episode_index {index} is out of range 0..{len(self.episodes) - 1}"
                )
            self._cursor = index
        elif "episode_id" in options:
            ids = [e.episode_id for e in self.episodes]
            if options["episode_id"] not in ids:
                raise EpisodeNotFoundError(f"unknown episode_id {options['episode_id']!r}")
            self._cursor = ids.index(options["episode_id"])
        episode = self.episodes[self._cursor % len(self.episodes)]
        self._cursor = (self._cursor + 1) % len(self.episodes)
        return episode

    def _load_scene(self, episode: Episode) -> NavGrid:
        try:  # the scene ids the server makes are sound: a bad one is the caller's mistake
            grid = self.sim.load_scene(episode.scene_id)
        except (SceneIdError, MeshSceneError, FileNotFoundError) as error:
            raise BadEpisodeError(f"episode {episode.episode_id}: scene_id: {error}") from None
        check_on_grid(episode, grid)
        return grid

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        if seed is not None:
            integer = isinstance(seed, (int, np.integer)) and not isinstance(seed, bool)
            if not (integer and 0 <= seed <= MAX_SEED):
                raise BadResetOptionError(
                    f"seed must be an int in [0, {MAX_SEED}], got {seed!r:.80}"
                )
            seed = int(seed)
        check_reset_options(options or {})
        super().reset(seed=seed)
        if seed is not None and self.episodes:
            self._cursor = seed % len(self.episodes)
        episode = self._next_episode(dict(options or {}))
        grid = self._load_scene(episode)
        start = np.asarray(episode.start_position[:2], dtype=np.float64)
        task = self.config.task
        self._fields = [
            self._field_cache.get(grid, np.asarray(g.position[:2]), task.goal_radius)
            for g in episode.goals
        ]
        optimal = []
        previous = start
        for index, field_ in enumerate(self._fields):
            d = float(grid.lookup(field_, previous, outside=np.inf))
            if not math.isfinite(d):
                raise BadEpisodeError(
                    f"episode {episode.episode_id}: goal {index} is unreachable in {episode.scene_id}"
                )
            optimal.append(d)
            previous = np.asarray(episode.goals[index].position[:2])
        assert self.sim.world is not None
        self._distractor_fields = {}
        cylinders = (*episode.goals, *episode.distractors) if task.goals_visible else ()
        if task.goal_set in OBJECT_GOAL_SETS:
            self.sim.world.place_object_goals(
                [(g.position, g.category, goal_yaw(episode.episode_id, i))
                 for i, g in enumerate(cylinders)],
                goal_categories(task.goal_set),
            )  # fmt: skip
        elif task.goal_set == "shapes":
            self.sim.world.place_shape_goals(
                [(g.position, g.category) for g in cylinders],
                task.shape_size,
                task.shape_support_height,
                SHAPE_RGBA,
            )
        else:
            self.sim.world.place_goals(
                [(g.position, GOAL_RGBA[g.category]) for g in cylinders],
                task.goal_radius,
                task.goal_height,
            )
        self.sim.set_agent(start, episode.start_yaw)
        self.episode = episode
        m = episode.num_goals
        self.state = EpisodeState(
            episode=episode,
            optimal_distances=tuple(optimal),
            position=self.sim.position.copy(),
            distance_to_goal=optimal[0],
            first_seen_step=[None] * m,
            current_since_step=[0] + [None] * (m - 1),
        )
        self._goals_seen = [False] * m
        self._update_seen()
        self.measures.reset(self.state)
        if uses_source(configured_sensors(self.config), "oracle_map"):
            if self._oracle is None or self._oracle.grid is not grid:
                self._oracle = OracleMap(grid, self.config.maps)
                self._reveal = EgoMapReveal(self._oracle, self.config.camera.hfov_deg)
            self._oracle.set_goals((*episode.goals, *episode.distractors))
            assert self._reveal is not None
            self._reveal.reset()
        self._done = False
        return self._observe(), self._info()

    def step(self, action: int) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        self.check_can_step()
        action = _check_action(action)
        assert self.state is not None  # check_can_step saw it
        state, task = self.state, self.config.task
        state.step += 1
        state.found_correct = state.found_wrong = False
        reward = task.slack_reward
        terminated = False
        if action == Action.FOUND:
            if state.distance_to_goal <= task.success_distance:
                state.found_correct = True
                state.goals_found += 1
                reward += task.goal_reward
                if state.goals_found == len(self._fields):
                    state.end_reason, terminated = "success", True
                    state.distance_to_goal = 0.0
                else:
                    state.current_since_step[state.goals_found] = state.step
                    state.distance_to_goal = self._distance(state.goals_found)
            else:
                state.found_wrong = True
                state.wrong_founds += 1
                state.distractor_founds += int(self._at_distractor())
                reward -= task.wrong_found_penalty
                if state.wrong_founds > task.found_budget:
                    state.end_reason, terminated = "wrong_found", True
            state.collided = False
        else:
            state.collided = self.sim.act(action)
            state.position = self.sim.position.copy()
            previous = state.distance_to_goal
            state.distance_to_goal = self._distance(state.goals_found)
            reward += previous - state.distance_to_goal
        truncated = not terminated and state.step >= task.max_steps
        if truncated:
            state.end_reason = "max_steps"
        self._update_seen()
        self.measures.update(state)
        self._done = terminated or truncated
        return self._observe(), float(reward), terminated, truncated, self._info()

    def observe_pose(self, position: np.ndarray, yaw: float) -> dict[str, np.ndarray]:
        """The observation from another pose in this episode's house, for offline data (vision
        pretraining, probes of a policy's features). The agent is moved there without a step
        and the episode is over: it is neither stepped nor scored from a pose it did not walk
        to."""
        if self.state is None:
            raise EpisodeOverError("no episode: call reset() before observe_pose()")
        self.sim.set_agent(np.asarray(position, dtype=np.float64)[:2], float(yaw))
        self._done = True
        return self._observe()

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        if self._last_rgb is None:
            self._last_rgb = self.sim.render().rgb
        return self._last_rgb

    def close(self) -> None:
        self.sim.close()
        if self._goal_sites is not None:  # its share of the process's cache budget
            self._goal_sites.close()

    # ------------------------------------------------------------------ helpers
    @property
    def episode_over(self) -> bool:
        return self._done

    def check_can_step(self) -> None:
        """Raise :class:`EpisodeOverError` unless an episode is under way: the one place that
        decides it (``step`` asks, and so does the server's worker before stepping any env)."""
        if self._done or self.state is None:
            raise EpisodeOverError("the episode is over; call reset() before step()")

    def metrics(self) -> dict[str, Any]:
        return self.measures.values()

    def _distance(self, goal_index: int) -> float:
        assert self.sim.grid is not None
        return float(
            self.sim.grid.lookup(self._fields[goal_index], self.sim.position, outside=np.inf)
        )

    def _at_distractor(self) -> bool:
        """Is the agent within the success distance of a distractor? (fields made on demand)"""
        assert self.episode is not None and self.sim.grid is not None
        for index, distractor in enumerate(self.episode.distractors):
            if index not in self._distractor_fields:
                self._distractor_fields[index] = distance_field(
                    self.sim.grid, np.asarray(distractor.position[:2]), self.config.task.goal_radius
                )
            distance = self.sim.grid.lookup(
                self._distractor_fields[index], self.sim.position, outside=np.inf
            )
            if float(distance) <= self.config.task.success_distance:
                return True
        return False

    def _update_seen(self) -> None:
        state, grid = self.state, self.sim.grid
        assert state is not None and grid is not None and self.episode is not None
        for index, goal in enumerate(self.episode.goals):
            if state.first_seen_step[index] is None and can_see(
                grid,
                self.sim.position,
                self.sim.yaw,
                np.asarray(goal.position[:2]),
                self.config.camera.hfov_deg,
                self.config.maps.view_distance,
            ):
                state.first_seen_step[index] = state.step
            if self._tracks_goal_pose and not self._goals_seen[index]:
                self._goals_seen[index] = can_see(
                    grid,
                    self.sim.position,
                    self.sim.yaw,
                    np.asarray(goal.position[:2]),
                    self.config.camera.hfov_deg,
                    GOAL_VECTOR_SEEN_DISTANCE,
                )

    def _info(self) -> dict[str, Any]:
        assert self.episode is not None
        return {
            "episode_id": self.episode.episode_id,
            "scene_id": self.episode.scene_id,
            "metrics": self.measures.values(),
        }

    def _observe(self) -> dict[str, np.ndarray]:
        state, episode = self.state, self.episode
        assert state is not None and episode is not None
        sensors = configured_sensors(self.config)
        frame: Frame | None = None
        if uses_source(sensors, "camera"):
            goal_mask = "goal_mask" in self.config.sensors
            image = self.sim.render(segmentation=goal_mask)
            mask = self._goal_mask(image.segmentation) if goal_mask else None
            frame = Frame(image.rgb, image.depth, mask)
        self._last_rgb = frame.rgb if frame is not None else None
        crops = None
        if self._oracle is not None and uses_source(sensors, "oracle_map"):
            assert self._reveal is not None
            crops = PoseCrops(self._oracle, self._reveal, self.sim.position, self.sim.yaw)
        current = min(state.goals_found, episode.num_goals - 1)
        inputs = SensorInputs(
            frame=frame,
            goal_category=episode.goals[current].category,
            distance_to_goal=state.distance_to_goal,
            position=self.sim.position,
            yaw=self.sim.yaw,
            start_position=np.asarray(episode.start_position[:2]),
            start_yaw=episode.start_yaw,
            oracle=crops,
            goal_position=np.asarray(episode.goals[current].position[:2], dtype=np.float64)
            if self._tracks_goal_pose
            else None,
            goal_seen=self._tracks_goal_pose and self._goals_seen[current],
        )
        return {sensor.spec.name: sensor.observe(inputs) for sensor in sensors}

    def _goal_mask(self, segmentation: np.ndarray | None) -> np.ndarray:
        assert segmentation is not None and self.episode is not None and self.sim.world is not None
        mask = np.zeros(segmentation.shape, dtype=np.uint8)
        if not self.config.task.goals_visible:
            return mask
        cylinders = (*self.episode.goals, *self.episode.distractors)
        for body, goal in zip(self.sim.world.goal_bodies_in_use, cylinders, strict=True):
            mask[segmentation == body] = goal.category + 1
        return mask


def _check_action(action: Any) -> int:
    value = action_id(action)
    if value is None:
        raise IllegalActionError(
            f"illegal action {action!r:.80}; actions are integers: {ACTIONS_TEXT}"
        )
    return value


def make_env(
    num_goals: int = 3,
    config: EnvConfig | None = None,
    episodes: Sequence[Episode] | None = None,
    render_mode: str | None = None,
    num_distractors: int = 0,
) -> MultiONEnv:
    """Entry point of the registered ids: the default config for ``num_goals`` (and
    ``num_distractors``) unless one is given."""
    if config is None:
        config = EnvConfig(task=TaskConfig(num_goals=num_goals, num_distractors=num_distractors))
    return MultiONEnv(config, episodes=episodes, render_mode=render_mode)
