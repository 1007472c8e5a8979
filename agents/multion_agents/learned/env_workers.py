"""Several local training environments per worker process.

Gymnasium's ``AsyncVectorEnv`` runs one environment per process, so each process imports
PyBullet, builds its own scenes and holds its own goal-site cache (one per process, see
docs/training-speed.md). :class:`SharedProcessVectorEnv` runs ``per_process`` environments in each
worker process, stepped one after the other in a loop, so those environments share the
process's cache and modules.

It behaves as an ``AsyncVectorEnv`` of the same environments with ``AutoresetMode.SAME_STEP``:
environment ``i`` is seeded ``seed + i`` at ``reset(seed=...)``; the step that ends an episode
resets it and returns the finished episode's info under ``final_info`` and its last observation
under ``final_obs``. A rollout is therefore the same whatever the number per process.
"""

from __future__ import annotations

import multiprocessing
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array

EnvFactory = Callable[[], gym.Env]
StepAnswer = tuple[Any, float, bool, bool, dict[str, Any]]


def _step_with_autoreset(env: gym.Env, action: Any) -> StepAnswer:
    """One step, as gymnasium's async worker does it in ``SAME_STEP`` mode."""
    observation, reward, terminated, truncated, info = env.step(action)
    if terminated or truncated:
        reset_observation, reset_info = env.reset()
        info = {"final_info": info, "final_obs": observation, **reset_info}
        observation = reset_observation
    return observation, float(reward), bool(terminated), bool(truncated), info


def _worker(connection: Connection, factories: Sequence[EnvFactory]) -> None:
    """A worker process's loop: builds its environments, then answers the parent's commands
    (``("reset", seeds)``, ``("step", actions)``, ``("close", None)``) with ``(True, answer)``,
    or ``(False, traceback)`` when an environment raised."""
    envs: list[gym.Env] = []
    try:
        envs = [factory() for factory in factories]
        connection.send((True, (envs[0].observation_space, envs[0].action_space, envs[0].metadata)))
        while True:
            command, data = connection.recv()
            if command == "reset":
                connection.send(
                    (True, [env.reset(seed=seed) for env, seed in zip(envs, data, strict=True)])
                )
            elif command == "step":
                answers = [_step_with_autoreset(env, a) for env, a in zip(envs, data, strict=True)]
                connection.send((True, answers))
            elif command == "close":
                connection.send((True, None))
                return
            else:
                raise ValueError(f"unknown worker command {command!r}")
    except KeyboardInterrupt:
        return
    except Exception:  # the parent raises it with the worker's traceback
        connection.send((False, traceback.format_exc()))
    finally:
        for env in envs:
            env.close()
        connection.close()


class WorkerError(RuntimeError):
    """An environment in a worker process raised; the message holds the worker's traceback."""


class SharedProcessVectorEnv(VectorEnv):
    """``len(factories)`` environments, ``per_process`` of them in each spawned worker
    process (the last one may hold fewer)."""

    def __init__(self, factories: Sequence[EnvFactory], per_process: int) -> None:
        if per_process < 1:
            raise ValueError(f"envs per process {per_process}: at least 1")
        if not factories:
            raise ValueError("a vector env needs at least one environment")
        context = multiprocessing.get_context("spawn")
        self.num_envs = len(factories)
        self._counts: list[int] = []
        self._connections: list[Connection] = []
        self._processes: list[multiprocessing.process.BaseProcess] = []
        self._closed = False
        for first in range(0, self.num_envs, per_process):
            batch = list(factories[first : first + per_process])
            parent, child = context.Pipe()
            process = context.Process(target=_worker, args=(child, batch), daemon=True)
            process.start()
            child.close()
            self._counts.append(len(batch))
            self._connections.append(parent)
            self._processes.append(process)
        answers = self._receive_all()
        observation_space, action_space, metadata = answers[0]
        self.single_observation_space = observation_space
        self.single_action_space = action_space
        self.observation_space = batch_space(observation_space, self.num_envs)
        self.action_space = batch_space(action_space, self.num_envs)
        self.metadata = {**metadata, "autoreset_mode": AutoresetMode.SAME_STEP}

    @property
    def worker_pids(self) -> list[int]:
        """The process ids of this vector env's simulator processes."""
        return [process.pid for process in self._processes if process.pid is not None]

    def _receive_all(self) -> list[Any]:
        answers, errors = [], []
        for index, connection in enumerate(self._connections):
            ok, answer = connection.recv()
            if ok:
                answers.append(answer)
            else:
                errors.append(f"worker process {index}:\n{answer}")
        if errors:
            self.close(terminate=True)
            raise WorkerError("\n".join(errors))
        return answers

    def _new_batch(self) -> Any:
        # a fresh array each step: the caller may keep the previous step's observations
        return create_empty_array(self.single_observation_space, self.num_envs, fn=np.zeros)

    def _per_worker(self, values: Sequence[Any]) -> list[list[Any]]:
        out, first = [], 0
        for count in self._counts:
            out.append(list(values[first : first + count]))
            first += count
        return out

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset every environment (environment ``i`` seeded ``seed + i`` when a seed is given)."""
        if options:
            raise ValueError("reset options are not supported by shared-process envs")
        seeds = [None if seed is None else seed + i for i in range(self.num_envs)]
        for connection, batch in zip(self._connections, self._per_worker(seeds), strict=True):
            connection.send(("reset", batch))
        results = [pair for answer in self._receive_all() for pair in answer]
        infos: dict[str, Any] = {}
        for index, (_, info) in enumerate(results):
            infos = self._add_info(infos, info, index)
        observations = concatenate(
            self.single_observation_space, [obs for obs, _ in results], self._new_batch()
        )
        return observations, infos

    def step_async(self, actions: np.ndarray) -> None:
        """Send each worker its environments' actions (they start stepping at once)."""
        for connection, batch in zip(
            self._connections, self._per_worker(list(actions)), strict=True
        ):
            connection.send(("step", batch))

    def step_wait(self) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """The step's observations, rewards, terminated, truncated flags and infos."""
        results = [step for answer in self._receive_all() for step in answer]
        infos: dict[str, Any] = {}
        for index, result in enumerate(results):
            infos = self._add_info(infos, result[4], index)
        observations = concatenate(
            self.single_observation_space, [r[0] for r in results], self._new_batch()
        )
        rewards = np.array([r[1] for r in results], dtype=np.float64)
        terminated = np.array([r[2] for r in results], dtype=np.bool_)
        truncated = np.array([r[3] for r in results], dtype=np.bool_)
        return observations, rewards, terminated, truncated, infos

    def step(self, actions: np.ndarray) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict]:
        self.step_async(actions)
        return self.step_wait()

    def close_extras(self, terminate: bool = False) -> None:
        if self._closed:
            return
        self._closed = True
        for connection, process in zip(self._connections, self._processes, strict=True):
            if not terminate and process.is_alive():
                try:
                    connection.send(("close", None))
                    connection.recv()
                except (BrokenPipeError, EOFError):
                    pass  # the worker already ended
            connection.close()
        for process in self._processes:
            if terminate:
                process.terminate()
            process.join(timeout=10)
