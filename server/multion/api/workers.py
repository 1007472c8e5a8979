"""The pool of simulator worker processes, seen from the server's event loop.

PyBullet holds the GIL while it renders, so environments live in worker processes (started with
the *spawn* context; one duplex Pipe each) and the event loop only moves bytes. Replies are read
with ``loop.add_reader`` on the pipe, so awaiting a worker blocks neither the loop nor a thread.

A worker that dies (or does not answer within ``timeout_s`` and is killed) is detected at once:
pending and later requests for it raise :class:`WorkerFailed`, ``on_death`` is called so the
sessions pinned to it can be marked failed, and a fresh worker takes its slot.

As with any use of the spawn context, a script that runs the app in its own process (rather
than through ``multion serve`` or uvicorn) must guard its entry point with
``if __name__ == "__main__":``, since each worker re-imports the main module.
"""

from __future__ import annotations

import asyncio
import contextlib
import multiprocessing
import os
import socket
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

from multion.api.reply_buffer import ReplyBuffer
from multion.api.turns import TurnQueue
from multion.api.worker_entry import run_worker
from multion.task.memory import ProcessShare, mib
from multion_client.errors import MemoryBudgetExceeded, WorkerFailed
from multion_client.protocol import decode

Reply = tuple[dict[str, Any], list[bytes]]
PIPE_BUFFER_BYTES = 8 * 1024 * 1024
RESTART_DELAY_S = 5.0
WORKER_RESERVED_BYTES = 1024 * 2**20
"""Address space a worker needs besides its sessions' estimates: the interpreter, PyBullet and
numpy (about 330 MiB of address space when idle), the navigable-grid cache, allocator slack."""


@dataclass(frozen=True)
class WorkerReport:
    """What a worker says in its ready message, learnt in the worker so that the server process
    never loads the simulator to find it out."""

    pid: int
    renderer_auto: str | None = None
    """What ``camera.renderer = "auto"`` renders with in the worker (``gl`` or ``tiny``)."""
    gl_unavailable: str | None = None
    """Why ``auto`` falls back to TinyRenderer there (None where ``gl`` runs)."""
    env_metadata: dict[str, Any] = field(default_factory=dict)
    """The env class's Gymnasium metadata (render modes, fps)."""

    @classmethod
    def from_ready(cls, header: dict[str, Any]) -> WorkerReport:
        renderer = header.get("renderer") or {}
        return cls(
            pid=int(header["pid"]),
            renderer_auto=renderer.get("auto"),
            gl_unavailable=renderer.get("gl_unavailable"),
            env_metadata=dict(header.get("env_metadata") or {}),
        )


class Worker:
    """One simulator process and the server's end of its pipe; it answers one request at a time."""

    def __init__(
        self,
        slot: int,
        generation: int,
        on_exit: Callable[[Worker], None],
        memory_limit_bytes: int,
    ) -> None:
        ctx = multiprocessing.get_context("spawn")
        self.slot = slot
        self.generation = generation
        self.memory_limit_bytes = memory_limit_bytes
        self.env_count = 0
        self.env_bytes = 0
        """The memory estimates of the environments this worker holds, each its own."""
        self.plain_env_bytes = 0
        """… of which those of plain sessions (not leaderboard runs)."""
        self.share_claims: dict[str, tuple[ProcessShare, bool]] = {}
        """Per shard that shares something with the process's other envs (a goal-site cache,
        an OpenGL context): what, and whether it is a plain session's."""
        self.alive = True
        self.failure = ""
        self._loop = asyncio.get_running_loop()
        self._on_exit = on_exit
        self._turns = TurnQueue()  # steps before resets and creations (see .turns)
        self._waiter: asyncio.Future[Reply] | None = None
        self.ready: asyncio.Future[WorkerReport] = self._loop.create_future()
        self.conn, child = ctx.Pipe(duplex=True)
        _widen(self.conn, child)
        self.buffer: ReplyBuffer | None = ReplyBuffer.create()
        buffer_name = None if self.buffer is None else (self.buffer.name, self.buffer.size)
        self.process = ctx.Process(
            target=run_worker,
            args=(child, memory_limit_bytes, buffer_name),
            name=f"multion-worker-{slot}",
            daemon=True,
        )
        self.process.start()
        child.close()  # so that the worker's death shows up as EOF on our end
        self._fd = self.conn.fileno()
        self._loop.add_reader(self._fd, self._on_readable)
        # uvloop (libuv) makes a watched fd non-blocking; the reads and writes here rely on a
        # blocking pipe (a reply's parts are read in one go), and readiness works either way.
        os.set_blocking(self._fd, True)

    @property
    def pid(self) -> int | None:
        return self.process.pid

    def share(self, plain_only: bool = False) -> ProcessShare:
        """What this process's envs share (one goal-site cache, sized for the largest budget
        its shards ask for, :class:`multion.task.goal_sites.SiteFieldCache`; one OpenGL
        context); ``plain_only``: for plain sessions' shards."""
        share = ProcessShare()
        for claim, plain in self.share_claims.values():
            if plain or not plain_only:
                share = share.merged(claim)
        return share

    @property
    def reserved_bytes(self) -> int:
        """The memory estimates of what this worker holds: its environments and, once, what
        they share."""
        return self.env_bytes + self.share().total

    @property
    def plain_bytes(self) -> int:
        """… of which plain sessions' (a shared part counts where a plain session uses it)."""
        return self.plain_env_bytes + self.share(plain_only=True).total

    def hold(
        self, shard_id: str, count: int, env_bytes: int, share: ProcessShare, plain: bool
    ) -> None:
        """Reserve a shard of ``count`` environments of ``env_bytes`` each, sharing ``share``
        with the process's other envs."""
        self.env_count += count
        self.env_bytes += count * env_bytes
        if plain:
            self.plain_env_bytes += count * env_bytes
        if share.total:
            self.share_claims[shard_id] = (share, plain)

    def release(self, shard_id: str, count: int, env_bytes: int, plain: bool) -> None:
        """Undo :meth:`hold` (a shared part is freed with the last shard using it)."""
        self.env_count -= count
        self.env_bytes -= count * env_bytes
        if plain:
            self.plain_env_bytes -= count * env_bytes
        self.share_claims.pop(shard_id, None)

    @property
    def free_bytes(self) -> int:
        """What more environments may reserve on this worker."""
        return self.memory_limit_bytes - WORKER_RESERVED_BYTES - self.reserved_bytes

    async def request(self, command: str, shard_id: str, payload: Any, timeout_s: float) -> Reply:
        """Send one command and await its reply (header, raw parts)."""
        if not self.ready.done():  # a fresh replacement still importing the simulator
            await asyncio.wait_for(asyncio.shield(self.ready), timeout_s)
        async with self._turns.turn(urgent=command == "step"):
            if not self.alive:
                raise WorkerFailed(self.failure)
            waiter: asyncio.Future[Reply] = self._loop.create_future()
            self._waiter = waiter
            try:
                self.conn.send((command, shard_id, payload))
            except OSError as error:
                self._died(f"simulator worker {self.pid} cannot be reached ({error})")
            # A timer rather than asyncio.wait_for, which costs a task per request: on time-out
            # the worker is killed, and its death fails the waiter with WorkerFailed.
            timer = self._loop.call_later(timeout_s, self._timed_out, command, timeout_s)
            try:
                return await waiter
            finally:
                timer.cancel()
                self._waiter = None

    def _timed_out(self, command: str, timeout_s: float) -> None:
        self.kill(f"simulator worker {self.pid} did not answer {command} in {timeout_s} s")

    def kill(self, reason: str) -> None:
        """Stop the process now (no reply expected) and mark the worker failed."""
        if self.process.is_alive():
            self.process.kill()
        self._died(reason)

    async def stop(self, timeout_s: float = 5.0) -> None:
        """Ask the worker to exit; kill it if it does not."""
        if self.alive:
            self._on_exit = _ignore  # a requested exit is not a death to report
            try:
                self.conn.send(("shutdown", "", None))
            except OSError:
                pass
            await asyncio.to_thread(self.process.join, timeout_s)
        self.kill("the server is shutting down")

    # ------------------------------------------------------------------ internals
    def _on_readable(self) -> None:
        try:
            header = decode(self.conn.recv_bytes())
            # The parts follow the header at once, so these reads do not wait.
            parts = [self.conn.recv_bytes() for _ in range(int(header.get("parts", 0)))]
            if "buffered" in header and self.buffer is not None:
                # now, before anything else is sent to the worker: its next reply reuses it
                parts = self.buffer.read(header.pop("buffered"))
        except (EOFError, OSError):
            self._died(None)
            return
        except ValueError as error:
            self.kill(f"simulator worker {self.pid} sent a malformed reply ({error})")
            return
        if header.get("ready"):
            if not self.ready.done():
                self.ready.set_result(WorkerReport.from_ready(header))
            return
        if self._waiter is not None and not self._waiter.done():
            self._waiter.set_result((header, parts))

    def _died(self, reason: str | None) -> None:
        if not self.alive:
            return
        self.alive = False
        self._loop.remove_reader(self._fd)
        self.process.join(timeout=1.0)  # it closed its pipe, so it is exiting; reap it
        self.failure = reason or (
            f"simulator worker {self.pid} died (exit code {self.process.exitcode}); "
            "the sessions it held are lost: close them and create new ones"
        )
        self.conn.close()
        if self.buffer is not None:
            self.buffer.close()
            self.buffer = None
        error = WorkerFailed(self.failure)
        for future in (self._waiter, self.ready):
            if future is not None and not future.done():
                future.set_exception(error)
                future.exception()  # mark retrieved: nobody may be waiting on it
        self._on_exit(self)


def _widen(*conns: Connection) -> None:
    """Ask for big socket buffers, so that a reply of a few images crosses the pipe in a few
    system calls (the kernel caps the size; a failure only costs speed)."""
    for conn in conns:
        try:
            sock = socket.socket(fileno=os.dup(conn.fileno()))
        except OSError:
            continue
        with sock:
            for option in (socket.SO_SNDBUF, socket.SO_RCVBUF):
                with contextlib.suppress(OSError):
                    sock.setsockopt(socket.SOL_SOCKET, option, PIPE_BUFFER_BYTES)


def _ignore(worker: Worker) -> None:
    pass


class WorkerPool:
    """``size`` worker slots; a slot whose worker dies gets a new worker at once."""

    def __init__(self, size: int, start_timeout_s: float, memory_limit_bytes: int) -> None:
        self.size = size
        self.start_timeout_s = start_timeout_s
        self.memory_limit_bytes = memory_limit_bytes
        self.workers: list[Worker] = []
        self.on_death: Callable[[Worker], None] = _ignore
        self.replaced = 0
        self._stopping = False

    async def start(self) -> None:
        """Start every worker and wait until each has imported the simulator."""
        self.workers = [
            Worker(slot, 0, self._exited, self.memory_limit_bytes) for slot in range(self.size)
        ]
        await asyncio.wait_for(
            asyncio.gather(*(w.ready for w in self.workers)), self.start_timeout_s
        )

    async def stop(self) -> None:
        self._stopping = True
        await asyncio.gather(*(worker.stop() for worker in self.workers))

    async def report(self) -> WorkerReport | None:
        """The ready message of the first worker that starts (each describes the same machine);
        None when no worker is running."""
        for worker in self.workers:
            if not worker.alive:
                continue
            try:
                return await asyncio.wait_for(asyncio.shield(worker.ready), self.start_timeout_s)
            except (WorkerFailed, asyncio.TimeoutError):
                continue
        return None

    @property
    def capacity_bytes(self) -> int:
        """What one worker's environments may reserve in all."""
        return self.memory_limit_bytes - WORKER_RESERVED_BYTES

    def choose(
        self,
        num_envs: int,
        env_bytes: int,
        share: ProcessShare = ProcessShare(),
        plain_cap_bytes: int | None = None,
    ) -> list[tuple[Worker, int]]:
        """Spread ``num_envs`` environments of ``env_bytes`` each over the least loaded live
        workers with memory to spare: [(worker, count), ...]; raises
        :class:`MemoryBudgetExceeded` when they do not fit now. ``share``: what they share
        with the other envs of their process (a goal-site cache, an OpenGL context), so a
        worker reserves it (or what it lacks of it) with its first environment of this
        session. With ``plain_cap_bytes`` (a plain session on a server that keeps room for
        runs) a worker's plain sessions may reserve no more than that in all."""
        live = [w for w in self.workers if w.alive]
        if not live:
            raise WorkerFailed("no simulator worker is running")
        load = {id(w): w.env_count for w in live}
        free = {id(w): w.free_bytes for w in live}
        share_lacking = {id(w): _lacking(w.share(), share) for w in live}
        if plain_cap_bytes is not None:
            plain_free = {id(w): plain_cap_bytes - w.plain_bytes for w in live}
            plain_share_lacking = {id(w): _lacking(w.share(plain_only=True), share) for w in live}
        counts: dict[int, int] = {}

        def fits(w: Worker) -> bool:
            first = id(w) not in counts
            if free[id(w)] < env_bytes + (share_lacking[id(w)] if first else 0):
                return False
            if plain_cap_bytes is None:
                return True
            return plain_free[id(w)] >= env_bytes + (plain_share_lacking[id(w)] if first else 0)

        def take(w: Worker) -> None:
            first = id(w) not in counts
            load[id(w)] += 1
            free[id(w)] -= env_bytes + (share_lacking[id(w)] if first else 0)
            if plain_cap_bytes is not None:
                plain_free[id(w)] -= env_bytes + (plain_share_lacking[id(w)] if first else 0)
            counts[id(w)] = counts.get(id(w), 0) + 1

        spare = free if plain_cap_bytes is None else {k: min(free[k], plain_free[k]) for k in free}
        initial = ", ".join(f"{mib(max(0, spare[id(w)]))} MiB" for w in live)
        kept = "" if plain_cap_bytes is None else " for plain sessions: the rest is kept for runs"
        shared = f", plus {share.describe()} once per worker" if share.total else ""
        for placed in range(num_envs):
            room = [w for w in live if fits(w)]
            if not room:
                raise MemoryBudgetExceeded(
                    f"{num_envs} environment(s) of this config need up to {mib(env_bytes)} MiB "
                    f"each{shared}; the simulator workers have room for {placed} now ({initial} "
                    f"free{kept}). Close sessions, retry later, or use fewer environments, "
                    "smaller images or a coarser navgrid.cell_size"
                )
            take(min(room, key=lambda w: (load[id(w)], w.slot)))
        return [(w, counts[id(w)]) for w in live if id(w) in counts]

    def _exited(self, worker: Worker) -> None:
        self.on_death(worker)
        if self._stopping or self.workers[worker.slot] is not worker:
            return
        if worker.ready.done() and worker.ready.exception() is None:
            self._replace(worker)
        else:  # it died while starting: retry later rather than respawn in a tight loop
            asyncio.get_running_loop().call_later(RESTART_DELAY_S, self._replace, worker)

    def _replace(self, worker: Worker) -> None:
        if not self._stopping and self.workers[worker.slot] is worker:
            self.replaced += 1
            self.workers[worker.slot] = Worker(
                worker.slot, worker.generation + 1, self._exited, self.memory_limit_bytes
            )


def _lacking(held: ProcessShare, wanted: ProcessShare) -> int:
    """What a process that shares ``held`` must add to share ``wanted`` as well."""
    return held.merged(wanted).total - held.total
