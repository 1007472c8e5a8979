"""``RemoteVectorEnv``: many MultiON environments on one or several servers, as one vector env."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar, cast

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array

from multion_client.client import DEFAULT_TIMEOUT_S, Client
from multion_client.constants import ACTIONS_TEXT
from multion_client.errors import InvalidAction, MultiONError
from multion_client.protocol import SessionInfo

T = TypeVar("T")


class RemoteVectorEnv(VectorEnv):
    """``sum(envs_per_server)`` environments: one auto-resetting session per server.

    Each ``step`` sends one HTTP request per server (all servers at once, from a small thread
    pool), and each server steps its environments in its simulator workers.

    Autoreset follows Gymnasium's ``AutoresetMode.SAME_STEP`` (done on the server): when an
    environment's episode ends at a step, that step returns its reward and
    ``terminated``/``truncated`` flags, but the returned observation is already the *first
    observation of the next episode*. The last observation of the ended episode is in
    ``infos["final_obs"][i]`` and its info (with the final ``metrics``) in
    ``infos["final_info"]``, both masked by ``infos["_final_obs"]`` / ``infos["_final_info"]``;
    the other info keys are the new episode's reset info. So there is never a step whose action
    is ignored, exactly like ``SyncVectorEnv(..., autoreset_mode=AutoresetMode.SAME_STEP)``.

    ``infos`` use Gymnasium's vector layout: each key maps to an array over environments plus
    a boolean ``_key`` mask (nested dicts, such as ``metrics``, recursively).
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(
        self,
        urls: Sequence[str],
        envs_per_server: int | Sequence[int],
        config: Mapping[str, Any] | None = None,
        *,
        timeout: float = DEFAULT_TIMEOUT_S,
        retries: int = 3,
    ) -> None:
        # what close() frees, set first: Gymnasium calls close() from __del__ even when
        # __init__ raised
        self.clients: list[Client] = []
        self.sessions: list[SessionInfo] = []
        self._owners: list[int] = []
        self._pool: ThreadPoolExecutor | None = None
        if not urls:
            raise ValueError("RemoteVectorEnv needs at least one server URL")
        counts = (
            [envs_per_server] * len(urls)
            if isinstance(envs_per_server, int)
            else list(envs_per_server)
        )
        if len(counts) != len(urls) or min(counts) < 1:
            raise ValueError(f"envs_per_server must be ≥ 1 per server, got {envs_per_server!r}")
        self.counts = counts
        self.num_envs = sum(counts)
        self.clients = [Client(url, timeout=timeout, retries=retries) for url in urls]
        # One thread per server, created once: steps go to every server concurrently.
        self._pool = ThreadPoolExecutor(len(urls), "multion-vec") if len(urls) > 1 else None
        outcomes = self._each(lambda k: self._create(k, config))
        self.sessions = [o for o in outcomes if isinstance(o, SessionInfo)]
        if len(self.sessions) != len(urls):
            self._owners = [k for k, o in enumerate(outcomes) if isinstance(o, SessionInfo)]
            self.close()  # frees the sessions that were created
            raise next(o for o in outcomes if isinstance(o, BaseException))
        self._owners = list(range(len(urls)))
        first = self.sessions[0]
        for session in self.sessions[1:]:
            if session.observation_space != first.observation_space:
                self.close()
                raise ValueError("the servers disagree on the observation space for this config")
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._starts = np.cumsum([0, *counts]).tolist()

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: Mapping[str, Any] | Sequence[Mapping[str, Any] | None] | None = None,
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Reset all environments. An int ``seed`` gives env i the seed ``seed + i``; a list
        is per env. ``options`` is one dict for every env, or a list of per-env dicts."""
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, int):
            seeds = [seed + i for i in range(n)]
        else:
            seeds = list(seed)
        per_env = (
            [options] * n if options is None or isinstance(options, Mapping) else list(options)
        )
        if len(seeds) != n or len(per_env) != n:
            raise ValueError(f"reset: need {n} seeds and options, got {len(seeds)}, {len(per_env)}")
        results = self._each(
            lambda k: self.clients[k].reset(
                self.sessions[k].session_id,
                seeds=self._part(seeds, k),
                options=self._part(per_env, k),
            )
        )
        observations = [obs for result in results for obs in result.observations]
        infos: dict[str, Any] = {}
        for i, info in enumerate(info for result in results for info in result.infos):
            infos = self._add_info(infos, info, i)
        return self._batch(observations), infos

    def step(
        self, actions: Any
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        array = np.asarray(actions).reshape(-1)
        if array.dtype.kind not in "iu":
            raise InvalidAction(
                f"step: actions must be integers ({ACTIONS_TEXT}), got dtype {array.dtype}"
            )
        actions = [int(a) for a in array]
        if len(actions) != self.num_envs:
            raise ValueError(f"step: need {self.num_envs} actions, got {len(actions)}")
        results = self._each(
            lambda k: self.clients[k].step(self.sessions[k].session_id, self._part(actions, k))
        )
        infos: dict[str, Any] = {}
        for i, info in enumerate(info for result in results for info in result.infos):
            infos = self._add_info(infos, info, i)
        return (
            self._batch([obs for result in results for obs in result.observations]),
            np.array([r for result in results for r in result.rewards], dtype=np.float64),
            np.array([t for result in results for t in result.terminated], dtype=np.bool_),
            np.array([t for result in results for t in result.truncated], dtype=np.bool_),
            infos,
        )

    def close_extras(self, **kwargs: Any) -> None:
        for k, session in zip(self._owners, self.sessions, strict=True):
            try:
                self.clients[k].close_session(session.session_id)
            except MultiONError:
                pass  # already gone: nothing left to free
        for client in self.clients:
            client.close()
        if self._pool is not None:
            self._pool.shutdown(wait=True)

    # ------------------------------------------------------------------ helpers
    def _create(self, k: int, config: Mapping[str, Any] | None) -> SessionInfo | MultiONError:
        try:
            return self.clients[k].create_session(config, self.counts[k], auto_reset=True)
        except MultiONError as error:
            return error

    def _each(self, call: Callable[[int], T]) -> list[T]:
        """``call(k)`` for every server k, concurrently when there are several."""
        if self._pool is None:
            return [call(k) for k in range(len(self.clients))]
        return list(self._pool.map(call, range(len(self.clients))))

    def _part(self, values: Sequence[T], k: int) -> list[T]:
        return list(values[self._starts[k] : self._starts[k + 1]])

    def _batch(self, observations: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
        space = self.single_observation_space
        # A Dict space batches to a dict of arrays; gymnasium's signatures cover every kind of
        # space (and None for custom ones), hence the casts.
        out = cast(dict[str, np.ndarray], create_empty_array(space, self.num_envs))
        return cast(dict[str, np.ndarray], concatenate(space, observations, out))
