"""Every config of the benchmark, light to import: no PyBullet, torch or FastAPI.

Agents, the trainer, the server and the leaderboard all read the same frozen dataclasses, with
their valid ranges (:mod:`multion.config.ranges`), and the same dict codec
(:mod:`multion.config.codec`), so nothing copies a config to avoid loading the simulator. The
runtime modules (``multion.sim``, ``multion.task``, ``multion.scenes``, ``multion.api``) import
from here, never the reverse.

* :mod:`multion.config.sim`: ``CameraConfig``, ``AgentConfig``, ``NavGridConfig``
* :mod:`multion.config.task`: ``TaskConfig``, ``MapConfig``, ``EnvConfig``, ``EpisodeConstraints``
* :mod:`multion.config.sensors`: ``SensorSpec``, one per sensor (``SENSOR_SPECS``), and
  ``SENSORS``, their names (re-exported by :mod:`multion.config.task`)
* :mod:`multion.config.scenes`: ``HouseConfig``, ``PlanConfig``, ``PlacementConfig``, ``SPLITS``
* :mod:`multion.config.episode`: ``Episode`` and ``Goal``, the episodes a session may carry
* :mod:`multion.config.codec`: configs as nested dicts (the wire form) and back
"""
