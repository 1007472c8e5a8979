"""Habitat-style MultiON challenge agents against a leaderboard run, with one changed line.

A participant's ``evaluate.py`` from the MultiON challenges (3dlg-hcvc/multion-challenge, tags
``chal-2021`` and ``chal_2022``) runs unchanged but for the line ``import habitat``::

    import multion_client.habitat_compat as habitat   # was: import habitat
    from habitat.core.challenge import Challenge       # the 2021 starter's: works as it is

    class RandomWalker(habitat.Agent):
        def __init__(self, task_config: habitat.Config):           # the 2022 starter's
            self._POSSIBLE_ACTIONS = task_config.TASK.POSSIBLE_ACTIONS

        def reset(self):
            pass

        def act(self, observations):                  # 2022: one episode at a time
            return {"action": np.random.choice(self._POSSIBLE_ACTIONS)}  # an int, a name…

    config = habitat.get_config("./configs/multinav_real.yaml")     # the track's config
    habitat.Challenge().submit(RandomWalker(task_config=config))

Importing this module makes ``habitat.core.challenge`` name it (only that module path, so a
real habitat installed beside keeps its own ``habitat``), which is why the 2021 starter's second
import needs no change. ``Config`` and ``get_config`` are in :mod:`multion_client.habitat_config`.

The 2021 challenge's batched form, ``act(observations_list, not_done_masks)`` returning one
action per observation, is recognised by its two parameters and played over the run's lanes
(``MULTION_NUM_ENVS`` episodes at once, at most the challenge's ``max_envs_per_run`` and the
phase's episodes). ``not_done_masks`` is a float32 array of shape (K, 1), 0 for a lane whose
episode just started. Lane k stays at position k for the whole run, so state an agent keeps per
position never passes to another episode: a lane with no episode left keeps its place with its
last observation repeated and mask 1 until every lane is done, and its actions are ignored.

Where to play comes from the environment, as a habitat challenge reads its own: ``MULTION_SERVER``
(the URL), ``MULTION_TRACK``, ``MULTION_PHASE``, ``MULTION_METHOD`` (the name shown on the
leaderboard), ``MULTION_TOKEN``, and ``MULTION_RUN_ID`` to resume a run instead of creating one;
``Challenge(...)`` keywords override them. ``submit`` prints what ``multion submit`` prints: the
run's id as it starts, then its state and results. If the agent raises (or the process is
stopped by Ctrl-C or SIGTERM), the run is abandoned on the way out (its missing episodes count as
failures) unless ``Challenge(abandon_on_error=False)``; a lost connection leaves it running to
be resumed with ``MULTION_RUN_ID``.

Observations use the reference's names and conventions: ``rgb`` (H, W, 3) uint8, ``depth``
(H, W, 1) float32 in [0, 1] of 0-10 m, ``multiobjectgoal`` an int64 array of shape (1,) in the
reference's category order (red, green, blue, yellow, white, pink, black, cyan; on tracks with
other goal objects, their ids here), ``gps``
[forward, right] metres from the start, ``compass`` (1,) radians, counter-clockwise, and on tracks
that allow an oracle map ``semMap`` (S, S, 2), the reference's map cell for cell: the run asks
for ``maps.convention = "reference"`` (ahead down, as ``habitat/core/env.py`` l. 291-293 of
saimwani/multiON cuts it) and :mod:`multion_client.semantic_map` puts object ids in the reference's
order + 1 (``oracle_map``) or + 2 (``oracle_ego_map``, 1 for a seen cell without one).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from multion_client.constants import REFERENCE_TO_CATEGORY
from multion_client.errors import MultiONError, RunOver, ServerUnavailable
from multion_client.habitat_agent import Agent as Agent  # habitat.Agent (re-exported)
from multion_client.habitat_agent import (
    Observations,
    StopOnSigterm,
    is_batched,
    play_batched,
    play_one_by_one,
)
from multion_client.habitat_agent import to_action as to_action
from multion_client.habitat_config import SETTINGS as SETTINGS
from multion_client.habitat_config import Config as Config  # habitat.Config
from multion_client.habitat_config import find_track, setting
from multion_client.habitat_config import get_config as get_config  # habitat.get_config
from multion_client.run import RunEnv, describe_run
from multion_client.semantic_map import REFERENCE_MAPS, reference_sem_map

HABITAT_PATHS = ("habitat.core.challenge",)
"""The habitat module paths that name this module once it is imported (the starters' imports)."""
WANTED_SENSORS = ("rgb", "depth", "goal", "gps", "compass", "oracle_map", "oracle_ego_map")
REFERENCE_MAX_DEPTH = 10.0
"""Habitat's depth range, which the reference keeps: [0, 10] m, normalised."""
CATEGORY_TO_REFERENCE: tuple[int, ...] = tuple(
    REFERENCE_TO_CATEGORY.index(category) for category in range(len(REFERENCE_TO_CATEGORY))
)
"""The reference's index of each category id here."""


class DepthRange:
    """Turns a track's depth images into habitat's: [0, 1] of 0-10 m."""

    def __init__(self, camera: Mapping[str, Any]) -> None:
        self.low = float(camera.get("min_depth", 0.0))
        self.high = float(camera.get("max_depth", REFERENCE_MAX_DEPTH))
        self.normalized = bool(camera.get("normalize_depth", True))

    def __call__(self, depth: np.ndarray) -> np.ndarray:
        if self.normalized and (self.low, self.high) == (0.0, REFERENCE_MAX_DEPTH):
            return depth.astype(np.float32)
        metres = self.low + depth * (self.high - self.low) if self.normalized else depth
        return (np.clip(metres, 0.0, REFERENCE_MAX_DEPTH) / REFERENCE_MAX_DEPTH).astype(np.float32)


IDENTITY = tuple(range(len(CATEGORY_TO_REFERENCE)))
"""The order of the goal sets other than ``colours``, which the reference does not have."""


def habitat_observations(
    obs: Mapping[str, np.ndarray], depth: DepthRange, order: Sequence[int] = CATEGORY_TO_REFERENCE
) -> Observations:
    """This project's observation as the reference's (see the module docstring); ``order``:
    the id to give each category (the reference's colour order; :data:`IDENTITY` for goal sets
    it does not have)."""
    out: Observations = {}
    if "rgb" in obs:
        out["rgb"] = obs["rgb"]
    if "depth" in obs:
        out["depth"] = depth(obs["depth"])
    if "goal" in obs:
        goal = int(np.asarray(obs["goal"]).reshape(-1)[0])
        out["multiobjectgoal"] = np.array([order[goal]], dtype=np.int64)
    if "gps" in obs:
        ahead, left = (float(v) for v in np.asarray(obs["gps"]).reshape(-1)[:2])
        out["gps"] = np.array([ahead, -left], dtype=np.float32)
    if "compass" in obs:
        out["compass"] = np.asarray(obs["compass"], dtype=np.float32).reshape(1)
    if "oracle_map" in obs:
        out["semMap"] = reference_sem_map(obs["oracle_map"], "oracle_map", order)
    elif "oracle_ego_map" in obs:
        out["semMap"] = reference_sem_map(obs["oracle_ego_map"], "oracle_ego_map", order)
    return out


class Challenge:
    """habitat's ``Challenge``: ``submit(agent)`` plays one leaderboard run to its end, prints
    what ``multion submit`` prints and returns the run's results as the phase shows them."""

    def __init__(
        self,
        eval_remote: bool = False,
        *,
        server: str | None = None,
        track: str | None = None,
        phase: str | None = None,
        method: str | None = None,
        token: str | None = None,
        num_envs: int | None = None,
        run_id: str | None = None,
        abandon_on_error: bool = True,
    ) -> None:
        del eval_remote  # habitat's local/remote switch: a leaderboard run is always remote
        self.run_id = setting("run_id", run_id)
        given = {"server": server, "track": track, "phase": phase, "method": method}
        values = {k: setting(k, v) for k, v in given.items()}
        needed = ["server"] if self.run_id else list(given)  # a resumed run knows the rest
        missing = [SETTINGS[k] for k in needed if values[k] is None]
        if missing:
            raise ValueError(f"set {', '.join(missing)} (or pass them to Challenge())")
        self.server, self.track, self.phase, self.method = (values[k] or "" for k in given)
        self.token = token
        lanes = setting("num_envs", num_envs) or "4"
        try:
            self.num_envs = int(lanes)
        except ValueError:
            raise ValueError(f"{SETTINGS['num_envs']} must be an int ≥ 1, got {lanes!r}") from None
        if self.num_envs < 1:
            raise ValueError(f"{SETTINGS['num_envs']} must be an int ≥ 1, got {self.num_envs}")
        self.abandon_on_error = abandon_on_error
        self._depth = DepthRange({})  # both read from the track when a run opens
        self._order: Sequence[int] = CATEGORY_TO_REFERENCE

    def submit(self, agent: Agent) -> dict[str, Any]:
        """Play the run (or the rest of ``MULTION_RUN_ID``'s); its results as the phase shows
        them (empty while sealed). Printed: the run's id as it starts, its results at the end."""
        batched = is_batched(agent)
        lanes = self._open(self.num_envs if batched else 1)
        first = lanes[0]
        print(
            f"run {first.run_id}: {first.num_episodes} episodes, {len(lanes)} at once "
            f"(resume with {SETTINGS['run_id']}={first.run_id})",
            flush=True,
        )
        try:
            with StopOnSigterm():
                try:
                    play = play_batched if batched else play_one_by_one
                    play(agent, lanes, self._convert)
                except RunOver:
                    pass  # the server ended the run (time budget, timeouts): its status says why
            status = first.status()
        except ServerUnavailable:
            print(
                f"run {first.run_id}: the server cannot be reached; the run goes on: resume it "
                f"with {SETTINGS['run_id']}={first.run_id}",
                file=sys.stderr,
            )
            raise
        except BaseException as error:
            self._stop(first, error)
            raise
        finally:
            for env in lanes:
                env.close()
        print(describe_run(status), flush=True)
        return status.results or {}  # None on a sealed phase

    # ------------------------------------------------------------------ internals
    def _convert(self, obs: Mapping[str, np.ndarray]) -> Observations:
        return habitat_observations(obs, self._depth, self._order)

    def _open(self, num_envs: int) -> list[RunEnv]:
        """The lanes of a new run, or of run ``run_id`` resumed."""
        if self.run_id is not None:
            first = RunEnv(self.server, token=self.token, run_id=self.run_id)
            lanes = [first] + [
                RunEnv(self.server, token=self.token, run_id=self.run_id, lane=k)
                for k in range(1, first.num_envs)
            ]
            self.track = first.status().track
            self._read_track(find_track(self.server, self.track)[0])
            return lanes
        track, limits = find_track(self.server, self.track)
        sensors = self._read_track(track)
        phases: list[dict[str, Any]] = track.get("phases", [])
        phase = next((p for p in phases if p["name"] == self.phase), {})
        most = [int(limits.get("max_envs_per_run", num_envs)), int(phase.get("episodes", num_envs))]
        return RunEnv.lanes(
            self.server, self.track, self.phase, self.method, num_envs=min(num_envs, *most),
            token=self.token, sensors=sensors,
            maps=REFERENCE_MAPS if {"oracle_map", "oracle_ego_map"} & set(sensors) else None,
        )  # fmt: skip

    def _read_track(self, track: Mapping[str, Any]) -> list[str]:
        """Take the track's depth range and goal order; the sensors to ask for."""
        allowed = set(track.get("sensors", ()))
        sensors = [s for s in WANTED_SENSORS if s in allowed]
        if "oracle_map" in sensors and "oracle_ego_map" in sensors:
            sensors.remove("oracle_ego_map")  # one semMap: the full oracle's
        self._depth = DepthRange(track.get("camera") or {})
        colours = track.get("goal_set", "colours") == "colours"
        self._order = CATEGORY_TO_REFERENCE if colours else IDENTITY
        return sensors

    def _stop(self, env: RunEnv, error: BaseException) -> None:
        """The exit path after ``error``: abandon the run (unless told not to), or say how to
        resume it."""
        why = type(error).__name__
        if not self.abandon_on_error:
            print(
                f"run {env.run_id}: stopped by {why}; it goes on until it expires: resume it with "
                f"{SETTINGS['run_id']}={env.run_id}",
                file=sys.stderr,
            )
            return
        try:
            env.abandon()
        except MultiONError as failure:  # over already, or unreachable: nothing more to do
            print(f"run {env.run_id}: stopped by {why}; abandoning it failed: {failure}",
                  file=sys.stderr)  # fmt: skip
            return
        print(
            f"run {env.run_id}: abandoned after {why} (its missing episodes count as failures)",
            file=sys.stderr,
        )


for _path in HABITAT_PATHS:  # see the module docstring: the starters' own imports work
    sys.modules[_path] = sys.modules[__name__]
