"""habitat's ``Agent`` and how :mod:`multion_client.habitat_compat` plays one over a run's lanes.

Two forms of agent, told apart by ``act``'s parameters:

* the 2022 challenge's ``act(observations)``: one episode at a time, ``reset()`` before each;
* the 2021 challenge's ``act(observations_list, not_done_masks)``: a list in, one action per
  observation out, ``reset()`` once. Lane k of the run is position k of every list for the
  whole run (an agent keeps recurrent state per position); a lane with no episode left keeps
  its position with its last observation and mask 1, and its actions are ignored, so no
  position ever continues another episode's state.
"""

from __future__ import annotations

import inspect
import signal
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from types import FrameType, TracebackType
from typing import Any, Protocol

import numpy as np

from multion_client.constants import Action, action_id

Observations = dict[str, np.ndarray]
ActionChoice = int | str | Mapping[str, Any] | np.integer[Any]
Convert = Callable[[Mapping[str, np.ndarray]], Observations]
"""A run's observation as the agent's (habitat's names and conventions)."""


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


class Lane(Protocol):
    """What the play loops use of a lane's :class:`~multion_client.run.RunEnv`."""

    @property
    def run_done(self) -> bool: ...

    def reset(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]: ...

    def step(
        self, action: int
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]: ...


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


def play_one_by_one(agent: Agent, lanes: Sequence[Lane], convert: Convert) -> None:
    """The 2022 form: every episode of each lane in turn, ``reset()`` before each."""
    for lane in lanes:
        while not lane.run_done:
            obs, _ = lane.reset()
            agent.reset()
            done = False
            while not done:
                obs, _, terminated, truncated, _ = lane.step(to_action(agent.act(convert(obs))))
                done = terminated or truncated


def play_batched(agent: Agent, lanes: Sequence[Lane], convert: Convert) -> None:
    """The 2021 form over ``lanes`` at once, lane k at position k for the whole run."""
    agent.reset()
    batched_act: Any = agent.act  # the 2021 signature, not the base class's
    playing = [not lane.run_done for lane in lanes]
    if not any(playing):
        return
    shown: list[Observations | None] = [
        convert(lane.reset()[0]) if live else None
        for lane, live in zip(lanes, playing, strict=True)
    ]
    blank = {k: np.zeros_like(v) for k, v in next(o for o in shown if o is not None).items()}
    observations = [blank if o is None else o for o in shown]  # a lane done before it began
    masks = np.zeros((len(lanes), 1), dtype=np.float32)
    while any(playing):
        actions = list(batched_act(list(observations), masks.copy()))
        if len(actions) != len(lanes):
            raise ValueError(f"act() returned {len(actions)} actions for {len(lanes)} observations")
        for k, lane in enumerate(lanes):
            masks[k] = 1.0
            if not playing[k]:
                continue  # a finished lane keeps its place; its action is not played
            obs, _, terminated, truncated, _ = lane.step(to_action(actions[k]))
            if (terminated or truncated) and not lane.run_done:
                obs, _ = lane.reset()
                masks[k] = 0.0
            playing[k] = not lane.run_done
            observations[k] = convert(obs)


class StopOnSigterm:
    """While in effect, SIGTERM (``docker stop``, ``kill``) raises ``SystemExit(143)`` in the main
    thread, so a run's exit path runs; Python's default would end the process at once. Only
    where SIGTERM has its default handler and this is the main thread; restored on exit."""

    def __init__(self) -> None:
        self._previous: Any = None

    def __enter__(self) -> StopOnSigterm:
        main = threading.current_thread() is threading.main_thread()
        if main and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
            self._previous = signal.signal(signal.SIGTERM, _raise_exit)
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGTERM, self._previous)


def _raise_exit(signum: int, frame: FrameType | None) -> None:
    del frame
    raise SystemExit(128 + signum)
