"""The loop of a simulator worker process (started by ``workers.py`` with the spawn context).

A worker owns *shards*: the environments of one session that were pinned to it. It answers one
command at a time over its pipe. Requests are pickled tuples ``(command, shard_id, payload)``;
a reply is a msgpack header ``{"ok": bool, "parts": k, ...}`` and ``k`` raw byte strings: the
msgpack encodings of the per-env items (see ``protocol.encode_items``), which the server
splices into its HTTP response without decoding them. The parts follow the header on the pipe,
or, where the server gave the worker a :class:`~multion.api.reply_buffer.ReplyBuffer` and they
fit, lie in it with their lengths under the header's ``buffered``. This module never imports
FastAPI.
"""

from __future__ import annotations

import os
import traceback
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

from multion.api.reply_buffer import ReplyBuffer
from multion.common.processes import give_back_memory, ignore_stop_signals, limit_address_space
from multion.config.codec import session_config_from_dict
from multion.sim.camera import auto_renderer_elsewhere, resolve_renderer
from multion.task.env import MultiONEnv
from multion_client import errors
from multion_client.protocol import encode, encode_items, space_to_wire

Reply = tuple[dict[str, Any], list[bytes]]

INTERNAL_FAILURE = "the simulator failed on this request"
"""All a client learns of a bug in the simulator; the traceback goes to the server's log."""


@dataclass
class Shard:
    """The environments of one session held by this worker, and their latest outputs."""

    envs: list[MultiONEnv]
    auto_reset: bool
    observations: list[dict[str, Any]] = field(default_factory=list)
    infos: list[dict[str, Any]] = field(default_factory=list)


def worker_main(
    conn: Connection, memory_limit_bytes: int, reply_buffer: tuple[str, int] | None = None
) -> None:
    """Serve commands until ``shutdown``, until the server's end of the pipe closes, or until
    memory runs out (the worker then answers and exits: its state is not to be trusted, and the
    server replaces it). ``reply_buffer``: the name and size of the server's shared memory for
    this worker's replies."""
    ignore_stop_signals()  # Ctrl-C or SIGTERM reach the server too, which stops us in order
    # A bug or a bad estimate can cost this worker, never the machine. (The server already
    # lowered the limit to any outer one; the clamp is for apps built without that check.)
    memory_limit_bytes = limit_address_space(memory_limit_bytes)
    buffer = None if reply_buffer is None else ReplyBuffer.attach(*reply_buffer)
    shards: dict[str, Shard] = {}
    conn.send_bytes(encode(ready_message()))
    while True:
        try:
            command, shard_id, payload = conn.recv()
        except (EOFError, OSError):
            break  # the server is gone
        if command == "shutdown":
            break
        try:
            header, parts = handle(shards, command, shard_id, payload)
        except MemoryError:
            header, parts = _out_of_memory(command, memory_limit_bytes), []
        buffered = None if buffer is None or not parts else buffer.write(parts)
        if buffered is not None:
            header["buffered"], parts = buffered, []
        header["parts"] = len(parts)
        conn.send_bytes(encode(header))
        for part in parts:
            conn.send_bytes(part)
        if header.get("code") == errors.WorkerFailed.code:
            break
    for shard in shards.values():
        _close(shard)
    if buffer is not None:
        buffer.close()


def ready_message() -> dict[str, Any]:
    """What this worker tells the server once it has imported the simulator: its pid, what
    ``camera.renderer = "auto"`` renders with here (asked of a child process: a worker opens an
    OpenGL context only for envs that render with gl), and the env's metadata (read by
    ``GET /v1/spec``, so the server needs no simulator)."""
    auto, gl_unavailable = auto_renderer_elsewhere()
    renderer = {"auto": auto, "gl_unavailable": gl_unavailable}
    return {"ready": True, "pid": os.getpid(), "renderer": renderer, "env_metadata": env_metadata()}


def env_metadata() -> dict[str, Any]:
    """The env class's metadata, as declared. Gymnasium's vector envs before 1.4 write their
    ``autoreset_mode`` (an enum msgpack cannot encode) into the class's shared ``metadata`` dict
    when one is built in this process; the spec states the server's own autoreset mode apart."""
    return {key: value for key, value in MultiONEnv.metadata.items() if key != "autoreset_mode"}


def handle(shards: dict[str, Shard], command: str, shard_id: str, payload: Any) -> Reply:
    """Run one command; every failure becomes an error header with a code and a message.

    Bad input raises a wire error (the env's :mod:`~multion.task.errors` and the configs' errors
    derive from them): its own code, status and message are answered. Anything else is a bug:
    its header carries a generic message for the client and, under ``traceback``, the traceback
    that the server logs (``sessions.py``)."""
    try:
        if command == "create":
            return _create(shards, shard_id, payload)
        shard = shards.get(shard_id)
        if shard is None:
            raise errors.SessionNotFound(f"no shard {shard_id} in worker {os.getpid()}")
        if command == "reset":
            return _reset(shard, payload["seeds"], payload["options"])
        if command == "step":
            return _step(shard, payload["actions"])
        if command == "observe":
            return _observations(shard)
        if command == "close":
            _close(shards.pop(shard_id))
            give_back_memory()
            return {"ok": True}, []
        raise errors.BadRequest(f"unknown worker command {command!r}")
    except errors.MultiONError as error:
        return {
            "ok": False,
            "code": error.code,
            "status": error.status,
            "message": error.message,
        }, []
    except MemoryError:
        raise
    except Exception:  # noqa: BLE001 - a worker must answer, whatever happened
        header = {"ok": False, "code": errors.InternalError.code, "message": INTERNAL_FAILURE}
        return {**header, "traceback": f"{command} failed:\n{traceback.format_exc()}"}, []


def _create(shards: dict[str, Shard], shard_id: str, payload: dict[str, Any]) -> Reply:
    # The server checked the config and episodes: their errors reach only direct callers.
    config, episodes = session_config_from_dict(payload["config"])
    envs = [MultiONEnv(config, episodes) for _ in range(payload["num_envs"])]
    shards[shard_id] = Shard(envs, payload["auto_reset"])
    spaces = {
        "observation_space": space_to_wire(envs[0].observation_space),
        "action_space": space_to_wire(envs[0].action_space),
        "renderer": resolve_renderer(config.camera.renderer),
    }
    return {"ok": True}, [encode(spaces)]


def _reset(shard: Shard, seeds: list[int | None], options: list[dict[str, Any] | None]) -> Reply:
    shard.observations, shard.infos = [], []  # a failed reset leaves nothing to observe
    results = []
    for index, (env, seed, option) in enumerate(zip(shard.envs, seeds, options, strict=True)):
        try:
            results.append(env.reset(seed=seed, options=option))
        except errors.MultiONError as error:
            message = f"reset of environment {index} failed: {error.message}"
            raise _reworded(error, message) from None
    shard.observations = [obs for obs, _ in results]
    shard.infos = [info for _, info in results]
    return _observations(shard)


def _step(shard: Shard, actions: list[Any]) -> Reply:
    # The env decides whether it may step; all are asked before any steps, so a refused step
    # changes none of them. (The server refuses it before it gets here: a session's envs span
    # several workers. Only direct callers of a worker see this.)
    for index, env in enumerate(shard.envs):
        try:
            env.check_can_step()
        except errors.MultiONError as error:
            raise _reworded(error, f"environment {index}: {error.message}") from None
    rewards, terminated, truncated = [], [], []
    for index, (env, action) in enumerate(zip(shard.envs, actions, strict=True)):
        try:
            obs, reward, term, trunc, info = env.step(action)
        except errors.MultiONError as error:
            raise _reworded(error, f"environment {index}: {error.message}") from None
        if shard.auto_reset and (term or trunc):
            # Gymnasium SAME_STEP autoreset: the next episode's first observation, with the
            # ended episode's last observation and info under final_obs / final_info.
            final_obs, final_info = obs, info
            obs, info = env.reset()
            info = {"final_obs": final_obs, "final_info": final_info, **info}
        shard.observations[index], shard.infos[index] = obs, info
        rewards.append(reward)
        terminated.append(term)
        truncated.append(trunc)
    parts = [
        encode_items(shard.observations),
        encode_items(rewards),
        encode_items(terminated),
        encode_items(truncated),
        encode_items(shard.infos),
    ]
    done = [env.episode_over for env in shard.envs]
    return {"ok": True, "done": done}, parts


def _reworded(error: errors.MultiONError, message: str) -> errors.MultiONError:
    """``error``'s code and status with another message (one naming the shard's environment)."""
    return errors.MultiONError(message, code=error.code, status=error.status)


def _observations(shard: Shard) -> Reply:
    if not shard.observations:
        raise errors.NotReset("no episode has started in this session; call reset first")
    done = [env.episode_over for env in shard.envs]
    return {"ok": True, "done": done}, [
        encode_items(shard.observations),
        encode_items(shard.infos),
    ]


def _close(shard: Shard) -> None:
    for env in shard.envs:
        env.close()


def _out_of_memory(command: str, limit_bytes: int) -> dict[str, Any]:
    message = (
        f"simulator worker {os.getpid()} ran out of memory during {command} (its limit is "
        f"{limit_bytes // 2**20} MiB); it is being replaced and the sessions it held are lost"
    )
    return {"ok": False, "code": errors.WorkerFailed.code, "message": message}
