"""The registry of learned agents: every row of the paper's Table 3 and its ablations.

A :class:`ModelSpec` says how to build the agent's :class:`~multion_agents.learned.memory.Memory`
from the environment's observation space, whether it sees RGB-D, and which environment settings
it changes (e.g. hidden goal objects). ``multion train --agent NAME`` and
``multion eval --agent NAME --checkpoint PATH`` look names up in :data:`MODELS`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from gymnasium import spaces

from multion.config.codec import env_config_from_dict
from multion.config.task import EnvConfig
from multion.task.spaces import build_observation_space
from multion_agents.agent import AgentError
from multion_agents.learned.episodic import build_frmqn, build_smt
from multion_agents.learned.learned_maps import build_ego_map, build_proj_neural_map, obj_recog_map
from multion_agents.learned.map_ops import MapGeometry, default_geometry
from multion_agents.learned.memory import Memory
from multion_agents.learned.oracle_maps import OracleMapMemory
from multion_agents.learned.policy import HIDDEN_SIZE, RecurrentPolicy

MemoryBuilder = Callable[[spaces.Dict, MapGeometry, int], Memory | None]
"""Builds a memory from the env's observation space and map geometry (both from its config)
and the GRU's hidden size (memories that read the GRU state need it)."""


@dataclass(frozen=True)
class ModelSpec:
    name: str
    paper_name: str
    """The row of the paper's tables this model reproduces."""
    build_memory: MemoryBuilder
    use_rgb: bool = True
    use_depth: bool = True
    memory_sensors: tuple[str, ...] = ()
    """Observation keys the memory reads (so the env can be configured before building it)."""
    train_only_sensors: tuple[str, ...] = ()
    """Observation keys used only for auxiliary training losses."""
    config_overrides: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Environment config sections this model changes (as in ``Agent.config_overrides``)."""

    @property
    def sensors(self) -> tuple[str, ...]:
        own = ("rgb",) * self.use_rgb + ("depth",) * self.use_depth + ("goal",)
        return tuple(dict.fromkeys(own + self.memory_sensors))

    @property
    def train_sensors(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(self.sensors + self.train_only_sensors))

    def build(
        self,
        observation_space: spaces.Dict,
        geometry: MapGeometry | None = None,
        hidden_size: int = HIDDEN_SIZE,
        goal_heads: bool = False,
        found_head: bool = False,
        pose_input: bool = False,
        separate_critic: bool = False,
        found_head_reads_image: bool = False,
    ) -> RecurrentPolicy:
        """The policy for an env with ``observation_space`` whose config gives ``geometry``
        (None: the default env config's, for tests), with a GRU of ``hidden_size`` units and,
        with ``goal_heads``, the auxiliary goal heads (:mod:`.goal_heads`); with
        ``found_head``, FOUND decided by a supervised head (``--found-head``); with
        ``pose_input``, the GRU reading GPS and compass (``--pose-input``); with
        ``separate_critic``, the critic on its own GRU (``--separate-critic``); with
        ``found_head_reads_image``, the FOUND head reading the frame's embedding too."""
        memory = self.build_memory(observation_space, geometry or default_geometry(), hidden_size)
        return RecurrentPolicy(
            observation_space,
            memory,
            self.use_rgb,
            self.use_depth,
            hidden_size=hidden_size,
            goal_heads=goal_heads,
            found_head=found_head,
            pose_input=pose_input,
            separate_critic=separate_critic,
            found_head_reads_image=found_head_reads_image,
        )


def _oracle(sensor: str, channels: str = "occ+obj", dynamic: bool = False) -> MemoryBuilder:
    def build(observation_space: spaces.Dict, geometry: MapGeometry, hidden_size: int) -> Memory:
        return OracleMapMemory(observation_space, geometry.crop_size, sensor, channels, dynamic)

    return build


def _no_memory(observation_space: spaces.Dict, geometry: MapGeometry, hidden_size: int) -> None:
    return None


_SPECS = [
    ModelSpec("no-map", "NoMap (RNN)", _no_memory),
    ModelSpec(
        "oracle-map", "OracleMap (Occ+Obj)", _oracle("oracle_map"), memory_sensors=("oracle_map",)
    ),
    ModelSpec(
        "oracle-map-occ",
        "OracleMap (Occ)",
        _oracle("oracle_map", "occ"),
        memory_sensors=("oracle_map",),
    ),
    ModelSpec(
        "oracle-map-obj",
        "OracleMap (Obj)",
        _oracle("oracle_map", "obj"),
        memory_sensors=("oracle_map",),
    ),
    ModelSpec(
        "oracle-ego-map",
        "OracleEgoMap (Occ+Obj)",
        _oracle("oracle_ego_map"),
        memory_sensors=("oracle_ego_map",),
    ),
    # ablations (supplement)
    ModelSpec(
        "dynamic-oracle-map",
        "DynamicOracleMap",
        _oracle("oracle_map", dynamic=True),
        memory_sensors=("oracle_map",),
    ),
    ModelSpec(
        "only-oracle-map",
        "OnlyOracleMap (no RGB-D)",
        _oracle("oracle_map"),
        use_rgb=False,
        use_depth=False,
        memory_sensors=("oracle_map",),
    ),
    ModelSpec(
        "oracle-map-hidden-objects",
        "OracleMap, hidden goal objects",
        _oracle("oracle_map"),
        memory_sensors=("oracle_map",),
        config_overrides={"task": {"goals_visible": False}},
    ),
    ModelSpec(
        "dynamic-oracle-ego-map",
        "DynamicOracleEgoMap",
        _oracle("oracle_ego_map", dynamic=True),
        memory_sensors=("oracle_ego_map",),
    ),
    # implicit memory (episodic.py) and learned maps (learned_maps.py)
    ModelSpec("frmqn", "FRMQN", build_frmqn),
    ModelSpec("smt", "SMT", build_smt),
    ModelSpec(
        "obj-recog-map",
        "ObjRecogMap",
        obj_recog_map(),
        memory_sensors=("gps", "compass"),
        train_only_sensors=("goal_mask",),
    ),
    ModelSpec(
        "proj-neural-map",
        "ProjNeuralMap",
        build_proj_neural_map,
        memory_sensors=("depth", "gps", "compass"),
    ),
    ModelSpec("ego-map", "EgoMap", build_ego_map, memory_sensors=("depth", "gps", "compass")),
    ModelSpec(
        "dynamic-obj-recog-map",
        "DynamicObjRecogMap",
        obj_recog_map(dynamic=True),
        memory_sensors=("gps", "compass"),
        train_only_sensors=("goal_mask",),
    ),
]

MODELS: dict[str, ModelSpec] = {spec.name: spec for spec in _SPECS}


def model_spec(name: str) -> ModelSpec:
    """The spec registered as ``name``, or an AgentError listing the known names."""
    if name not in MODELS:
        raise AgentError(f"unknown learned agent {name!r}; known: {', '.join(MODELS)}")
    return MODELS[name]


def build_policy(
    agent: str,
    env_config: EnvConfig | Mapping[str, Any],
    hidden_size: int = HIDDEN_SIZE,
    goal_heads: bool = False,
    found_head: bool = False,
    pose_input: bool = False,
    separate_critic: bool = False,
    found_head_reads_image: bool = False,
) -> RecurrentPolicy:
    """The (untrained) policy of model ``agent`` for environments configured by ``env_config``
    (or its wire form, nested dicts), with a GRU of ``hidden_size`` units (768, the
    reference's, by default), with ``goal_heads``, the auxiliary goal heads, with
    ``found_head``, FOUND decided by a supervised head, with ``pose_input``, the GRU
    reading GPS and compass, with ``separate_critic``, the critic on its own GRU, and with
    ``found_head_reads_image``, the FOUND head reading the frame's embedding too."""
    if not isinstance(env_config, EnvConfig):
        env_config = env_config_from_dict(env_config)
    space = build_observation_space(env_config)
    geometry = MapGeometry.from_env_config(env_config)
    spec = model_spec(agent)
    return spec.build(
        space,
        geometry,
        hidden_size,
        goal_heads,
        found_head,
        pose_input,
        separate_critic,
        found_head_reads_image,
    )
