"""Habitat-style MultiON challenge agents against a leaderboard run, with one changed import.

A participant's ``evaluate.py`` from the MultiON challenges (3dlg-hcvc/multion-challenge) runs
unchanged but for its import::

    import multion_client.habitat_compat as habitat   # was: import habitat

    class RandomWalker(habitat.Agent):
        def reset(self):
            pass

        def act(self, observations):                  # 2022: one episode at a time
            return {"action": np.random.choice(4)}    # an int, a name, or {"action": ...}

    habitat.Challenge().submit(RandomWalker())

The 2021 challenge's batched form, ``act(observations_list, not_done_masks)`` returning one
action per observation, is recognised by its two parameters and played over the run's lanes
(``MULTION_NUM_ENVS`` episodes at once, the challenge's ``max_envs_per_run`` at most).
``not_done_masks`` is a float32 array of shape (K, 1), 0 for a lane whose episode just started;
a lane with no episode left leaves the batch, and the lists shrink, as habitat-baselines pauses
finished environments.

Where to play comes from the environment, as a habitat challenge reads its own: ``MULTION_SERVER``
(the URL), ``MULTION_TRACK``, ``MULTION_PHASE``, ``MULTION_METHOD`` (the name shown on the
leaderboard) and ``MULTION_TOKEN``; ``Challenge(...)`` keywords override them.

Observations use the reference's names and conventions: ``rgb`` (H, W, 3) uint8, ``depth``
(H, W, 1) float32 in [0, 1] of 0-10 m, ``multiobjectgoal`` an int64 array of shape (1,) in the
reference's category order (red, green, blue, yellow, white, pink, black, cyan; on tracks with
other goal objects, their ids here), ``gps``
[forward, right] metres from the start, ``compass`` (1,) radians, counter-clockwise, and on tracks
that allow an oracle map ``semMap`` (S, S, 2): occupancy, then object ids in the reference's order
+ 1 (``oracle_map``) or + 2 (``oracle_ego_map``) as the reference's ``habitat/core/env.py``
(saimwani/multiON, l. 252-253 and 279) writes them.
"""

from __future__ import annotations

import inspect
import os
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from multion_client.client import Client
from multion_client.constants import REFERENCE_TO_CATEGORY, Action, action_id
from multion_client.run import RunEnv

Observations = dict[str, np.ndarray]
ActionChoice = int | str | Mapping[str, Any] | np.integer[Any]
SETTINGS = {
    "server": "MULTION_SERVER",
    "track": "MULTION_TRACK",
    "phase": "MULTION_PHASE",
    "method": "MULTION_METHOD",
    "num_envs": "MULTION_NUM_ENVS",
}
"""Each setting of :class:`Challenge` and the environment variable it is read from."""
WANTED_SENSORS = ("rgb", "depth", "goal", "gps", "compass", "oracle_map", "oracle_ego_map")
REFERENCE_MAX_DEPTH = 10.0
"""Habitat's depth range, which the reference keeps: [0, 10] m, normalised."""
CATEGORY_TO_REFERENCE: tuple[int, ...] = tuple(
    REFERENCE_TO_CATEGORY.index(category) for category in range(len(REFERENCE_TO_CATEGORY))
)
"""The reference's index of each category id here."""


class Agent(ABC):
    """habitat's ``Agent``: subclass it and implement ``reset()`` and ``act(observations)``
    (abstract here, where habitat's raise when called: a subclass missing one is refused when
    it is made, not in the middle of a run)."""

    @abstractmethod
    def reset(self) -> None:
        """Called before each episode."""

    @abstractmethod
    def act(self, observations: Observations) -> ActionChoice:
        """The action for ``observations``: an int 0..3, a name such as ``"MOVE_FORWARD"``, or
        ``{"action": one of those}``."""


def to_action(choice: Any) -> int:
    """An agent's answer as an action id; a ``ValueError`` naming what is accepted."""
    value = choice.get("action") if isinstance(choice, Mapping) else choice
    if isinstance(value, str) and value.upper() in Action.__members__:
        return int(Action[value.upper()])
    number = action_id(value)
    if number is None:
        names = ", ".join(f"{a.value} or {a.name!r}" for a in Action)
        raise ValueError(
            f"act() returned {choice!r:.80}; an action is one of {names}, "
            "or {'action': one of those}"
        )
    return number


def is_batched(agent: Agent) -> bool:
    """True for the 2021 form ``act(observations_list, not_done_masks)``."""
    return len(inspect.signature(agent.act).parameters) == 2


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


def reference_map(
    crop: np.ndarray, offset: int, order: Sequence[int] = CATEGORY_TO_REFERENCE
) -> np.ndarray:
    """An oracle map crop with its object ids in ``order`` (the reference's), + ``offset``."""
    out = np.array(crop, copy=True)
    objects = out[..., 1]
    marked = objects > 0
    lookup = np.array(order, dtype=np.int64)
    objects[marked] = (lookup[objects[marked].astype(np.int64) - 1] + offset).astype(out.dtype)
    return out


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
        out["semMap"] = reference_map(obs["oracle_map"], 1, order)
    elif "oracle_ego_map" in obs:
        out["semMap"] = reference_map(obs["oracle_ego_map"], 2, order)
    return out


class Challenge:
    """habitat's ``Challenge``: ``submit(agent)`` plays one leaderboard run to its end and
    returns the run's results as the phase shows them."""

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
    ) -> None:
        del eval_remote  # habitat's local/remote switch: a leaderboard run is always remote
        given = {"server": server, "track": track, "phase": phase, "method": method}
        values = {k: v or os.environ.get(SETTINGS[k]) for k, v in given.items()}
        missing = [SETTINGS[k] for k, v in values.items() if not v]
        if missing:
            raise ValueError(f"set {', '.join(missing)} (or pass them to Challenge())")
        self.server, self.track, self.phase, self.method = (
            str(values[k]) for k in ("server", "track", "phase", "method")
        )
        self.token = token
        lanes = num_envs if num_envs is not None else os.environ.get(SETTINGS["num_envs"], "4")
        try:
            self.num_envs = int(lanes)
        except ValueError:
            raise ValueError(f"{SETTINGS['num_envs']} must be an int ≥ 1, got {lanes!r}") from None
        if self.num_envs < 1:
            raise ValueError(f"{SETTINGS['num_envs']} must be an int ≥ 1, got {self.num_envs}")
        self._depth = DepthRange({})  # both read from the track when a run opens
        self._order: Sequence[int] = CATEGORY_TO_REFERENCE

    def submit(self, agent: Agent) -> dict[str, Any]:
        """Play the run; its results as the phase shows them (empty while sealed)."""
        lanes = self._open(self.num_envs if is_batched(agent) else 1)
        try:
            if is_batched(agent):
                self._play_batched(agent, lanes)
            else:
                self._play(agent, lanes[0])
            return lanes[0].status().results or {}  # None on a sealed phase
        finally:
            for env in lanes:
                env.close()

    # ------------------------------------------------------------------ internals
    def _open(self, num_envs: int) -> list[RunEnv]:
        client = Client(self.server)
        try:
            info = client.challenge()
        finally:
            client.close()
        track = next((t for t in info["tracks"] if t["name"] == self.track), None)
        if track is None:
            names = [t["name"] for t in info["tracks"]]
            raise ValueError(f"no track {self.track!r} on {self.server}; tracks: {names}")
        allowed = set(track.get("sensors", ()))
        sensors = [s for s in WANTED_SENSORS if s in allowed]
        if "oracle_map" in sensors and "oracle_ego_map" in sensors:
            sensors.remove("oracle_ego_map")  # one semMap: the full oracle's
        self._depth = DepthRange(track.get("camera") or {})
        colours = track.get("goal_set", "colours") == "colours"
        self._order = CATEGORY_TO_REFERENCE if colours else IDENTITY
        limit = int(info["limits"].get("max_envs_per_run", num_envs))
        return RunEnv.lanes(
            self.server, self.track, self.phase, self.method, num_envs=min(num_envs, limit),
            token=self.token, sensors=sensors,
        )  # fmt: skip

    def _play(self, agent: Agent, env: RunEnv) -> None:
        while not env.run_done:
            obs, _ = env.reset()
            agent.reset()
            done = False
            while not done:
                action = to_action(agent.act(habitat_observations(obs, self._depth, self._order)))
                obs, _, terminated, truncated, _ = env.step(action)
                done = terminated or truncated

    def _play_batched(self, agent: Agent, lanes: Sequence[RunEnv]) -> None:
        agent.reset()
        active = [env for env in lanes if not env.run_done]
        observations: list[Mapping[str, np.ndarray]] = [env.reset()[0] for env in active]
        masks = np.zeros((len(active), 1), dtype=np.float32)
        batched_act: Any = agent.act  # the 2021 signature, not the base class's
        while active:
            batch = [habitat_observations(o, self._depth, self._order) for o in observations]
            actions = list(batched_act(batch, masks))
            if len(actions) != len(active):
                raise ValueError(
                    f"act() returned {len(actions)} actions for {len(active)} observations"
                )
            still: list[RunEnv] = []
            next_obs: list[Mapping[str, np.ndarray]] = []
            next_masks: list[float] = []
            for env, choice in zip(active, actions, strict=True):
                obs, _, terminated, truncated, _ = env.step(to_action(choice))
                if terminated or truncated:
                    if env.run_done:
                        continue  # this lane is finished: it leaves the batch
                    obs, _ = env.reset()
                    next_masks.append(0.0)
                else:
                    next_masks.append(1.0)
                still.append(env)
                next_obs.append(obs)
            active, observations = still, next_obs
            masks = np.array(next_masks, dtype=np.float32).reshape(-1, 1)
