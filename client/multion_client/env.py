"""``RemoteEnv``: one MultiON environment served by a MultiON server, as a Gymnasium env."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from multion_client.client import DEFAULT_TIMEOUT_S, Client
from multion_client.errors import MultiONError
from multion_client.protocol import SessionInfo


class RemoteEnv(gym.Env[dict[str, np.ndarray], int]):
    """A one-environment session on a server, with the same API as ``multion``'s MultiONEnv.

    ``config`` is the environment config as nested dicts, e.g.
    ``{"task": {"num_goals": 2}, "camera": {"width": 128, "height": 128}}``; it may also carry
    ``episodes`` (a list of Episode dicts). ``reset(seed=, options=)`` and ``step(action)``
    behave as in-process: same observations, rewards, termination and ``info["metrics"]``
    (computed by the server). Stepping an ended episode raises ``EpisodeOver`` (a
    ``RuntimeError``), an illegal action ``InvalidAction`` (a ``ValueError``).

    With ``lazy=True`` nothing is sent until the first ``reset`` or access to the spaces.
    ``close()`` closes the session on the server.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        base_url: str,
        config: Mapping[str, Any] | None = None,
        *,
        render_mode: str | None = None,
        timeout: float = DEFAULT_TIMEOUT_S,
        retries: int = 3,
        lazy: bool = False,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.config = dict(config or {})
        self.client = Client(base_url, timeout=timeout, retries=retries)
        self._info: SessionInfo | None = None
        self._last_obs: dict[str, np.ndarray] | None = None
        self._last_info: dict[str, Any] = {}
        if not lazy:
            self.connect()

    def connect(self) -> SessionInfo:
        """Create the server session if there is none yet; returns it."""
        if self._info is None:
            self._info = self.client.create_session(self.config, num_envs=1, auto_reset=False)
        return self._info

    @property
    def session(self) -> SessionInfo:
        """The server session, created on first use."""
        return self.connect()

    @property
    def session_id(self) -> str:
        return self.session.session_id

    # Read-only properties over gym.Env's attributes, so that a lazy env connects on first use
    # (mypy rejects a property that overrides a writable attribute, hence the ignores).
    @property
    def observation_space(self) -> spaces.Space[Any]:  # type: ignore[override]
        return self.session.observation_space

    @property
    def action_space(self) -> spaces.Space[Any]:  # type: ignore[override]
        return self.session.action_space

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        super().reset(seed=seed)
        result = self.client.reset(self.session_id, seeds=[seed], options=[options])
        self._last_obs, self._last_info = result.observations[0], result.infos[0]
        return self._last_obs, self._last_info

    def step(self, action: int) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        result = self.client.step(self.session_id, [action])
        self._last_obs, self._last_info = result.observations[0], result.infos[0]
        return (
            self._last_obs,
            float(result.rewards[0]),
            bool(result.terminated[0]),
            bool(result.truncated[0]),
            self._last_info,
        )

    def observe(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """The current observation and info again (no action)."""
        result = self.client.observe(self.session_id)
        return result.observations[0], result.infos[0]

    def metrics(self) -> dict[str, Any]:
        """The episode's measures as of the last reset or step."""
        return dict(self._last_info.get("metrics", {}))

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array" or self._last_obs is None:
            return None
        return self._last_obs.get("rgb")

    def close(self) -> None:
        if self._info is not None:
            try:
                self.client.close_session(self._info.session_id)
            except MultiONError:
                pass  # already gone (reaped, worker failed, server down): nothing left to free
            self._info = None
        self.client.close()
        super().close()
