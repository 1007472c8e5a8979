"""habitat's ``Config`` and ``get_config`` for MultiON challenge agents: the track's config.

The MultiON 2022 starter (3dlg-hcvc/multion-challenge, tag ``chal_2022``, ``evaluate.py`` l. 7-18)
loads a habitat YAML and gives it to its agent, which reads its actions from it::

    config = habitat.get_config("./configs/multinav_real.yaml")
    agent = RandomWalker(task_config=config)     # self._POSSIBLE_ACTIONS = config.TASK.POSSIBLE_ACTIONS

A leaderboard run has no habitat simulator to configure, so the file is not read, whatever path
is passed: the config describes the track the run will play (``MULTION_SERVER`` and
``MULTION_TRACK``, as :class:`~multion_client.habitat_compat.Challenge` reads them).

It holds every key of the reference's default config tree (386 keys, ``habitat_defaults.json``,
written by ``scripts/habitat_reference_keys.py``), the union of three yacs trees, each key's
default from the first that has it: 3dlg-hcvc/multion-challenge branch ``chal_2022``
``habitat/config/default.py`` (the 2022 starter's habitat: ``TASK.OBJECTS_TYPE = "CYL"`` at
l. 239), branch ``main`` ``multion/config/default_old.py`` (its 2023 additions: semantic map
sensors, ``AGENT_HEADING_SENSOR``, ...), and saimwani/multiON ``habitat/config/default.py`` (the
paper's and the 2021 challenge's: ``TASK.MULTI_GOAL_SENSOR``); each key's ``from`` in the data
file names its file and line. ``main``'s ``multion/config/default.py`` is habitat 0.2.5's hydra
config (lower-case ``habitat.task...`` keys, 2024), which no yacs starter reads: not covered.

Where the track decides a key (:func:`track_values`), the config has the track's value: the step
limit, the camera (``RGB_SENSOR``, ``DEPTH_SENSOR``, ``SEMANTIC_SENSOR``: size, HFOV, position),
the turn angle and step size, the agent's height and radius, the actions, the task sensors,
``OBJECTS_TYPE`` (``"CYL"`` for the coloured cylinders, ``"REAL"`` for the everyday objects), the
goals and distractors, every measure's success distance, ``DATASET.SPLIT`` (the phase). A
``MULTION`` section holds what habitat has no key for (the track, the goal set, the wrong-FOUND
budget, the sensors by this project's names). ``DEPTH_SENSOR`` says what the compat layer
delivers: [0, 1] of 0-10 m, whatever the track's camera. Other keys (``SIMULATOR.HABITAT_SIM_V0``,
the robot cameras, ``PYROBOT``, ...) configure habitat's simulator, which a run does not use:
they hold the reference's defaults, for agents that read them.
"""

from __future__ import annotations

import ast
import copy
import functools
import json
import os
from collections.abc import Mapping, Sequence
from importlib import resources
from typing import Any

from multion_client.client import Client
from multion_client.constants import DEFAULT_GOAL_SET, Action

SETTINGS = {
    "server": "MULTION_SERVER",
    "track": "MULTION_TRACK",
    "phase": "MULTION_PHASE",
    "method": "MULTION_METHOD",
    "num_envs": "MULTION_NUM_ENVS",
    "run_id": "MULTION_RUN_ID",
}
"""Each setting of ``Challenge`` / ``get_config`` and the environment variable it is read from."""

CAMERA_DEFAULTS: dict[str, Any] = {
    "width": 256,
    "height": 256,
    "hfov_deg": 79.0,
    "sensor_height": 0.88,
}
"""The server's camera defaults (``multion.config.CameraConfig``, which the light client may not
import; a test keeps the two equal) for the fields a track's ``camera`` leaves out."""
AGENT_DEFAULTS: dict[str, float] = {"forward_step": 0.25, "turn_angle_deg": 30.0, "radius": 0.1}
"""The server's ``AgentConfig`` defaults: a track cannot change them."""
HABITAT_SENSORS = {
    "goal": "MULTI_OBJECT_GOAL_SENSOR",
    "compass": "COMPASS_SENSOR",
    "gps": "GPS_SENSOR",
}
"""habitat's task sensor of each sensor here that the compat layer delivers."""
DEFAULTS_FILE = "habitat_defaults.json"
"""The reference's key tree as data, written by ``scripts/habitat_reference_keys.py``."""
OBJECTS_TYPES = {"colours": "CYL", "objects": "REAL"}
"""``TASK.OBJECTS_TYPE`` of a goal set: the reference's ``"CYL"`` (its CYLINDER track, the paper's
coloured cylinders) and ``"REAL"`` (its REAL-OBJECTS track; chal_2022 ``configs/multinav_cyl.yaml``
and ``multinav_real.yaml`` l. 32, ``habitat/config/default.py`` l. 239). The other goal sets here
(``shapes``, ``unseen_train``, ``unseen_test``) are neither: their names, upper-cased."""
SUCCESS_DISTANCE_KEYS = (
    "TASK.SUCCESS_DISTANCE",
    "TASK.SUCCESS.SUCCESS_DISTANCE",
    "TASK.SUB_SUCCESS.SUCCESS_DISTANCE",
    "TASK.PERCENTAGE_SUCCESS.SUCCESS_DISTANCE",
    "TASK.ORACLE_SUB_SUCCESS.SUCCESS_DISTANCE",
    "TASK.PROGRESS.SUCCESS_DISTANCE",
)
"""Every measure's success distance in the reference's tree: the track's, for all of them (the
reference's yaml sets ``SUCCESS``, ``SUB_SUCCESS`` and ``PERCENTAGE_SUCCESS`` to its own)."""
CAMERA_SENSORS = ("RGB_SENSOR", "DEPTH_SENSOR", "SEMANTIC_SENSOR")
"""The cameras the reference's yaml sizes alike (chal_2022 ``configs/multinav_real.yaml``): the
track's camera. The robot cameras of habitat's tree (``HEAD_RGB_SENSOR``, ...) keep its defaults."""


class Config(dict[str, Any]):
    """habitat's ``Config`` (a yacs ``CfgNode``): nested sections whose keys read as attributes
    (``config.TASK.POSSIBLE_ACTIONS``) or items. :func:`get_config` returns it frozen, as
    habitat does: ``defrost()`` before setting a key, ``freeze()`` after."""

    def __init__(self, values: Mapping[str, Any] | None = None) -> None:
        super().__init__()
        for key, value in (values or {}).items():
            self[key] = value

    def __setitem__(self, key: str, value: Any) -> None:
        if self.is_frozen():
            raise AttributeError(
                f"cannot set {key!r}: the config is frozen (call config.defrost() first)"
            )
        if isinstance(value, Mapping) and not isinstance(value, Config):
            value = Config(value)
        super().__setitem__(key, value)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):  # keep Python's protocols (copy, pickle) off the keys
            raise AttributeError(name)
        try:
            return self[name]
        except KeyError:
            raise AttributeError(f"the config has no key {name!r}; keys: {sorted(self)}") from None

    def __setattr__(self, name: str, value: Any) -> None:
        self[name] = value

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuilt, (dict(self), self.is_frozen()))

    def freeze(self) -> None:
        """Refuse changes, in every section."""
        self.__dict__["_frozen"] = True
        for value in self.values():
            if isinstance(value, Config):
                value.freeze()

    def defrost(self) -> None:
        """Allow changes again, in every section."""
        self.__dict__["_frozen"] = False
        for value in self.values():
            if isinstance(value, Config):
                value.defrost()

    def is_frozen(self) -> bool:
        return bool(self.__dict__.get("_frozen", False))

    def clone(self) -> Config:
        """A deep copy (frozen if this one is)."""
        return _rebuilt(self, self.is_frozen())

    def merge_from_list(self, opts: Sequence[Any]) -> None:
        """yacs's ``merge_from_list``: ``["TASK.SUCCESS_DISTANCE", 1.0, …]``; each key must exist
        (a ValueError names it), a string value is read as a Python literal where it is one."""
        if len(opts) % 2:
            raise ValueError(f"opts must alternate keys and values, got {len(opts)} items")
        for dotted, value in zip(opts[0::2], opts[1::2], strict=True):
            *sections, last = str(dotted).split(".")
            node: Any = self
            for part in sections:
                node = node.get(part) if isinstance(node, Config) else None
            if not isinstance(node, Config) or last not in node:
                raise ValueError(f"opts: the config has no key {dotted!r}")
            node[last] = _literal(value)


def _rebuilt(values: Mapping[str, Any], frozen: bool) -> Config:
    config = Config({k: _rebuilt(v, False) if isinstance(v, Mapping) else v
                     for k, v in values.items()})  # fmt: skip
    if frozen:
        config.freeze()
    return config


def _literal(value: Any) -> Any:
    if not isinstance(value, str):
        return value
    try:
        return ast.literal_eval(value)
    except (ValueError, SyntaxError):
        return value


def setting(key: str, given: Any = None) -> str | None:
    """``given``, else the environment variable of setting ``key`` (see :data:`SETTINGS`)."""
    value = given if given is not None else os.environ.get(SETTINGS[key])
    return None if value is None or value == "" else str(value)


def find_track(server: str, name: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """Track ``name`` as ``GET /v1/challenge`` describes it, and the challenge's limits; a
    ValueError naming the tracks there otherwise."""
    with Client(server) as client:
        info = client.challenge()
    track = next((t for t in info["tracks"] if t["name"] == name), None)
    if track is None:
        names = [t["name"] for t in info["tracks"]]
        raise ValueError(f"no track {name!r} on {server}; tracks: {names}")
    return track, dict(info.get("limits", {}))


def reference_defaults() -> dict[str, Any]:
    """Every key of the reference's default config tree and its default, ``{"A.B.C": value}``
    (``habitat_defaults.json``: see the module docstring for the trees, and each key's ``from``
    there for the file and line that sets it)."""
    return {path: copy.deepcopy(entry["value"]) for path, entry in _reference_keys().items()}


@functools.cache
def _reference_keys() -> dict[str, Any]:
    text = resources.files("multion_client").joinpath(DEFAULTS_FILE).read_text(encoding="utf-8")
    keys: dict[str, Any] = json.loads(text)["keys"]
    return keys


def objects_type(goal_set: str) -> str:
    """``TASK.OBJECTS_TYPE`` of a goal set (see :data:`OBJECTS_TYPES`)."""
    return OBJECTS_TYPES.get(goal_set, goal_set.upper())


def track_values(track: Mapping[str, Any], phase: str | None = None) -> dict[str, Any]:
    """The reference keys a run of ``track`` decides, ``{"A.B.C": value}``: the steps, the
    camera, the actions and motion, the goals, distractors and objects, the success distance
    (of every measure that has one), the sensors, the split."""
    camera = {**CAMERA_DEFAULTS, **track.get("camera", {})}
    sensors = list(track.get("sensors", ()))
    position = [0.0, float(camera["sensor_height"]), 0.0]
    success = float(track.get("success_distance", 1.5))
    distractors = int(track.get("num_distractors", 0))
    values: dict[str, Any] = {
        "ENVIRONMENT.MAX_EPISODE_STEPS": int(track["max_steps"]),
        "TASK.TOP_DOWN_MAP.MAX_EPISODE_STEPS": int(track["max_steps"]),
        "SIMULATOR.TURN_ANGLE": AGENT_DEFAULTS["turn_angle_deg"],
        "SIMULATOR.FORWARD_STEP_SIZE": AGENT_DEFAULTS["forward_step"],
        "SIMULATOR.AGENT_0.SENSORS": [
            f"{s.upper()}_SENSOR" for s in ("rgb", "depth") if s in sensors
        ],
        "SIMULATOR.AGENT_0.HEIGHT": position[1],  # the reference's yaml: the camera's height
        "SIMULATOR.AGENT_0.RADIUS": AGENT_DEFAULTS["radius"],
        # what the compat layer delivers: depth in [0, 1] of 0-10 m, whatever the track's camera
        "SIMULATOR.DEPTH_SENSOR.MIN_DEPTH": 0.0,
        "SIMULATOR.DEPTH_SENSOR.MAX_DEPTH": 10.0,
        "SIMULATOR.DEPTH_SENSOR.NORMALIZE_DEPTH": True,
        "TASK.TYPE": "MultiObjectNav-v1",
        "TASK.POSSIBLE_ACTIONS": [action.name for action in Action],
        "TASK.SENSORS": [habitat for s, habitat in HABITAT_SENSORS.items() if s in sensors],
        "TASK.GOAL_SENSOR_UUID": "multiobjectgoal",
        "TASK.OBJECTS_TYPE": objects_type(str(track.get("goal_set", DEFAULT_GOAL_SET))),
        "TASK.NUM_GOALS": int(track["num_goals"]),
        "TASK.NUM_DISTRACTORS": distractors,
        "TASK.INCLUDE_DISTRACTORS": distractors > 0,
        "DATASET.TYPE": "MultiObjectNav-v1",
        "DATASET.NUM_GOALS": int(track["num_goals"]),
        "DATASET.SPLIT": phase,
    }
    for measure in SUCCESS_DISTANCE_KEYS:
        values[measure] = success
    for sensor in CAMERA_SENSORS:
        values[f"SIMULATOR.{sensor}.WIDTH"] = int(camera["width"])
        values[f"SIMULATOR.{sensor}.HEIGHT"] = int(camera["height"])
        values[f"SIMULATOR.{sensor}.HFOV"] = float(camera["hfov_deg"])
        values[f"SIMULATOR.{sensor}.POSITION"] = list(position)
    return values


def track_config(track: Mapping[str, Any], phase: str | None = None) -> Config:
    """The habitat config of a run of ``track`` (a track of ``GET /v1/challenge``): every key of
    the reference's default tree (:func:`reference_defaults`), the track's values where the track
    decides them (:func:`track_values`), and the ``MULTION`` section."""
    flat = reference_defaults()
    for path, value in track_values(track, phase).items():
        if path not in flat:  # a key the reference does not have: this module's mistake
            raise KeyError(f"track_values sets {path!r}, which the reference's tree lacks")
        flat[path] = value
    tree: dict[str, Any] = {}
    for path, value in flat.items():
        *sections, last = path.split(".")
        node = tree
        for section in sections:
            node = node.setdefault(section, {})
        node[last] = value
    tree["MULTION"] = {
        "TRACK": track["name"],
        "NUM_GOALS": int(track["num_goals"]),
        "GOAL_SET": track.get("goal_set", DEFAULT_GOAL_SET),
        "FOUND_BUDGET": int(track.get("found_budget", 0)),
        "NUM_DISTRACTORS": int(track.get("num_distractors", 0)),
        "SENSORS": list(track.get("sensors", ())),
    }
    return Config(tree)


def get_config(
    config_paths: str | Sequence[str] | None = None, opts: Sequence[Any] | None = None
) -> Config:
    """habitat's ``get_config``: the config of the track a run will play (``MULTION_SERVER``,
    ``MULTION_TRACK``; ``MULTION_PHASE`` fills ``DATASET.SPLIT``), frozen. ``config_paths`` is
    not read, whatever it names (see the module docstring); ``opts`` as habitat's."""
    del config_paths  # a habitat YAML configures habitat's simulator, which a run does not use
    server, track = setting("server"), setting("track")
    if server is None or track is None:
        missing = [SETTINGS[k] for k, v in (("server", server), ("track", track)) if v is None]
        raise ValueError(
            f"get_config: set {', '.join(missing)}: the config is the track's, from the server"
        )
    config = track_config(find_track(server, track)[0], setting("phase"))
    if opts:
        config.merge_from_list(opts)
    config.freeze()
    return config
