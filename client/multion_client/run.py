"""``RunEnv``: a leaderboard run as a Gymnasium environment, for custom agents.

::

    from multion_client.run import RunEnv

    env = RunEnv("https://challenge.example.org", track="3-on", phase="minival",
                 method="my-agent")                       # token from $MULTION_TOKEN
    while not env.run_done:
        obs, info = env.reset()                           # the server's next hidden episode
        done = False
        while not done:
            obs, reward, terminated, truncated, info = env.step(my_agent(obs))
            done = terminated or truncated
    print(env.status().results)                           # what the phase shows

Several episodes at once (up to the challenge's ``max_envs_per_run``): ``RunEnv.lanes(url,
track, phase, method, num_envs=K)`` creates one run and returns K environments, one per lane,
to play from K threads (lane k plays the run's episodes k, k + K …; each its own agent).

The server picks the episodes and their order: ``reset`` takes no seed or options. Rewards are
always 0 (they would leak the geodesic distance); the metrics of an episode come in ``info``
at its end only on phases with per-episode feedback. A dropped connection is retried with the
same sequence number, so no action is taken twice; a crashed client resumes its run with
``RunEnv(..., run_id=ID)`` at the step where it stopped.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from multion_client.client import DEFAULT_TIMEOUT_S, Client
from multion_client.constants import ACTIONS_TEXT, NUM_ACTIONS, action_id
from multion_client.errors import EpisodeOver, InvalidAction, SequenceMismatch
from multion_client.run_protocol import CreateRun, RunInfo, RunObservation, RunStatus

TOKEN_ENV = "MULTION_TOKEN"
"""The environment variable a token is read from when none is given (keeps it out of shell
history)."""
TERMINAL_REASONS = ("success", "wrong_found")


def token_from_env(token: str | None) -> str:
    """``token``, or ``$MULTION_TOKEN``; a clear error if neither is set."""
    token = token or os.environ.get(TOKEN_ENV)
    if not token:
        raise ValueError(f"no leaderboard token: pass one or set the {TOKEN_ENV} variable")
    return token


class RunEnv(gym.Env[dict[str, np.ndarray], int | np.integer[Any]]):
    """One run of a challenge's (track, phase), created on construction (or resumed).

    Actions are ints or numpy integers in 0..3 (what ``action_space.sample()`` gives); a float,
    even ``1.0``, a bool or a string is refused with ``InvalidAction``, as the server refuses it.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        base_url: str,
        track: str | None = None,
        phase: str | None = None,
        method: str | None = None,
        *,
        token: str | None = None,
        sensors: Sequence[str] | None = None,
        maps: Mapping[str, Any] | None = None,
        paper_url: str | None = None,
        code_url: str | None = None,
        run_id: str | None = None,
        timeout: float = DEFAULT_TIMEOUT_S,
        retries: int = 30,
        num_envs: int = 1,
        lane: int = 0,
    ) -> None:
        self.client = Client(
            base_url, timeout=timeout, retries=retries, token=token_from_env(token)
        )
        self.lane = lane
        if run_id is None:
            if not (track and phase and method):
                raise ValueError("a new run needs track, phase and method (or give run_id)")
            message = CreateRun(
                track, phase, method, list(sensors) if sensors else None,
                dict(maps) if maps else None, paper_url, code_url, num_envs,
            )  # fmt: skip
            self.info: RunInfo | None = self.client.create_run(message)
            self.run_id = self.info.run_id
            self.observation_space = self.info.observation_space
            self.num_episodes = self.info.num_episodes
            self.num_envs = self.info.num_envs
            self._current: RunObservation | None = None
        else:
            self.info, self.run_id = None, run_id
            status = self.client.run_status(run_id)
            self.num_episodes = status.num_episodes
            self.num_envs = status.num_envs
            running = status.state == "running"
            self._current = self.client.run_observe(run_id, lane) if running else None
        if not 0 <= lane < self.num_envs:
            raise ValueError(f"lane must be in 0..{self.num_envs - 1}, got {lane}")
        self.action_space = gym.spaces.Discrete(4)
        self._run_done = run_id is not None and status.state != "running"

    @classmethod
    def lanes(
        cls,
        base_url: str,
        track: str,
        phase: str,
        method: str,
        *,
        num_envs: int,
        token: str | None = None,
        sensors: Sequence[str] | None = None,
        maps: Mapping[str, Any] | None = None,
        paper_url: str | None = None,
        code_url: str | None = None,
        timeout: float = DEFAULT_TIMEOUT_S,
    ) -> list[RunEnv]:
        """One new run playing ``num_envs`` episodes at once: an environment per lane (give
        each its own thread and agent; their connections are their own)."""
        first = cls(
            base_url, track, phase, method, token=token, sensors=sensors, maps=maps,
            paper_url=paper_url, code_url=code_url, timeout=timeout, num_envs=num_envs,
        )  # fmt: skip
        others = [
            cls(base_url, token=token, run_id=first.run_id, timeout=timeout, lane=k)
            for k in range(1, first.num_envs)
        ]
        for env in others:
            env.info, env.observation_space = first.info, first.observation_space
        return [first, *others]

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start the run's next episode (or, resuming, return the one in progress)."""
        if seed is not None or options:
            raise ValueError("a run's episodes are chosen by the server: no seed or options")
        current = self._current
        if current is not None and not current.done:
            return current.observation, self._info(current)  # resuming mid-episode
        next_episode = self._next_episode()
        if next_episode >= self.num_episodes:
            raise RuntimeError("the run has no episode left")
        try:
            self._current = self.client.start_episode(self.run_id, next_episode)
        except SequenceMismatch:  # episodes expired meanwhile: ask where the lane stands
            self._current = self.client.run_observe(self.run_id, self.lane)
            return self.reset()
        return self._current.observation, self._info(self._current)

    def step(
        self, action: int | np.integer[Any]
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        number = action_id(action)
        if number is None:  # refused here as the server and the in-process env refuse it
            raise InvalidAction(
                f"RunEnv.step: illegal action {action!r:.60}; an action is an integer in "
                f"[0, {NUM_ACTIONS - 1}]: {ACTIONS_TEXT}"
            )
        current = self._current
        if current is None or current.done:
            raise RuntimeError("the episode is over (or has not started); call reset()")
        try:
            answer = self.client.run_step(self.run_id, current.episode, current.seq + 1, number)
        except EpisodeOver as error:  # too late: the server ended the episode as it stood
            answer = dataclasses.replace(current, done=True, end_reason="timeout")
            self._current = answer
            info = {**self._info(answer), "message": error.message}
            return answer.observation, 0.0, False, True, info
        self._current = answer
        self._run_done = answer.run_done
        terminated = answer.done and answer.end_reason in TERMINAL_REASONS
        truncated = answer.done and not terminated
        return answer.observation, 0.0, terminated, truncated, self._info(answer)

    def close(self) -> None:
        """Close the connection; the run itself goes on (``abandon()`` ends it)."""
        self.client.close()

    # ------------------------------------------------------------------ run
    @property
    def run_done(self) -> bool:
        """No episode left (also true when the run ended early)."""
        if self._run_done:
            return True
        current = self._current
        last = current is not None and current.done and self._next_episode() >= self.num_episodes
        return last or (current is not None and current.run_done)

    @property
    def episodes_started(self) -> int:
        """Episodes this lane has started (all the run's, with one lane)."""
        if self._current is None or self._current.episode < 0:
            return 0
        return self._current.episode // self.num_envs + 1

    @property
    def episodes_finished(self) -> int:
        """Episodes this lane has played to their end (a resumed episode in progress is not
        one of them: a progress count starts here)."""
        current = self._current
        in_progress = current is not None and current.episode >= 0 and not current.done
        return self.episodes_started - int(in_progress)

    def _next_episode(self) -> int:
        """The run-order number of this lane's next episode (lane k: k, k + K …)."""
        current = self._current
        if current is None or current.episode < 0:
            return self.lane
        return current.episode + self.num_envs

    def status(self) -> RunStatus:
        return self.client.run_status(self.run_id)

    def abandon(self) -> RunStatus:
        self._run_done = True
        return self.client.abandon_run(self.run_id)

    @staticmethod
    def _info(answer: RunObservation) -> dict[str, Any]:
        info: dict[str, Any] = {"episode": answer.episode, "seq": answer.seq}
        if answer.done:
            info["end_reason"] = answer.end_reason
            if answer.metrics is not None:
                info["metrics"] = answer.metrics
        return info


def describe_run(status: RunStatus) -> str:
    """What ``multion submit`` prints at the end of a run: its state and episodes completed,
    then the results the phase shows (mean and 95% interval of each metric, the ranking one
    marked)."""
    lines = [
        f"run {status.run_id}: {status.state}"
        + (f" ({status.end_reason})" if status.end_reason else "")
        + f", {status.episodes_done}/{status.num_episodes} episodes completed"
    ]
    if status.refunded:
        lines.append(
            "  results: none (the server broke the run: refunded, not counted in the quota)"
        )
    elif status.results:
        primary = status.results.get("primary", "ppl")
        for name in ("ppl", "progress", "success", "spl"):
            value = status.results[name]
            mark = " (ranking)" if name == primary else ""
            lines.append(
                f"  {name:<9} {100 * value['mean']:6.1f}%  "
                f"[{100 * value['low']:.1f}, {100 * value['high']:.1f}]{mark}"
            )
    else:
        lines.append("  results: not shown for this phase (yet)")
    return "\n".join(lines)
