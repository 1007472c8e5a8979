"""habitat's ``Config`` and ``get_config`` for MultiON challenge agents: the track's config.

The MultiON 2022 starter (3dlg-hcvc/multion-challenge, tag ``chal_2022``, ``evaluate.py`` l. 7-18)
loads a habitat YAML and gives it to its agent, which reads its actions from it::

    config = habitat.get_config("./configs/multinav_real.yaml")
    agent = RandomWalker(task_config=config)     # self._POSSIBLE_ACTIONS = config.TASK.POSSIBLE_ACTIONS

A leaderboard run has no habitat simulator to configure, so the file is not read, whatever path
is passed: the config describes the track the run will play (``MULTION_SERVER`` and
``MULTION_TRACK``, as :class:`~multion_client.habitat_compat.Challenge` reads them), with the
reference's key names (``configs/multinav_real.yaml`` there; saimwani/multiON
``configs/tasks/multinav_mp3d.yaml``): ``ENVIRONMENT.MAX_EPISODE_STEPS``,
``SIMULATOR.{TURN_ANGLE, FORWARD_STEP_SIZE, AGENT_0, RGB_SENSOR, DEPTH_SENSOR}``,
``TASK.{TYPE, POSSIBLE_ACTIONS, SUCCESS_DISTANCE, SENSORS, GOAL_SENSOR_UUID}``,
``DATASET.SPLIT`` (the phase), and a ``MULTION`` section with what habitat has no key for
(the number of goals, the goal set, the wrong-FOUND budget, the sensors by this project's names).
``DEPTH_SENSOR`` says what the compat layer delivers: [0, 1] of 0-10 m, whatever the track's
camera.
"""

from __future__ import annotations

import ast
import os
from collections.abc import Mapping, Sequence
from typing import Any

from multion_client.client import Client
from multion_client.constants import Action

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


def track_config(track: Mapping[str, Any], phase: str | None = None) -> Config:
    """The habitat config of a run of ``track`` (a track of ``GET /v1/challenge``)."""
    camera = {**CAMERA_DEFAULTS, **track.get("camera", {})}
    sensors = list(track.get("sensors", ()))
    position = [0.0, float(camera["sensor_height"]), 0.0]
    image = {
        "WIDTH": int(camera["width"]),
        "HEIGHT": int(camera["height"]),
        "HFOV": float(camera["hfov_deg"]),
        "POSITION": position,
    }
    config = Config(
        {
            "ENVIRONMENT": {"MAX_EPISODE_STEPS": int(track["max_steps"])},
            "SIMULATOR": {
                "TURN_ANGLE": AGENT_DEFAULTS["turn_angle_deg"],
                "FORWARD_STEP_SIZE": AGENT_DEFAULTS["forward_step"],
                "AGENT_0": {
                    "SENSORS": [f"{s.upper()}_SENSOR" for s in ("rgb", "depth") if s in sensors],
                    "HEIGHT": position[1],  # the reference's yaml: the camera's height
                    "RADIUS": AGENT_DEFAULTS["radius"],
                },
                "RGB_SENSOR": dict(image),
                "DEPTH_SENSOR": {
                    **image,
                    "MIN_DEPTH": 0.0,
                    "MAX_DEPTH": 10.0,
                    "NORMALIZE_DEPTH": True,
                },
            },
            "TASK": {
                "TYPE": "MultiObjectNav-v1",
                "POSSIBLE_ACTIONS": [action.name for action in Action],
                "SUCCESS_DISTANCE": float(track.get("success_distance", 1.5)),
                "SENSORS": [habitat for s, habitat in HABITAT_SENSORS.items() if s in sensors],
                "GOAL_SENSOR_UUID": "multiobjectgoal",
            },
            "DATASET": {"TYPE": "MultiObjectNav-v1", "SPLIT": phase},
            "MULTION": {
                "TRACK": track["name"],
                "NUM_GOALS": int(track["num_goals"]),
                "GOAL_SET": track.get("goal_set", "colours"),
                "FOUND_BUDGET": int(track.get("found_budget", 0)),
                "NUM_DISTRACTORS": int(track.get("num_distractors", 0)),
                "SENSORS": sensors,
            },
        }
    )
    return config


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
