"""Sessions: the registry, its limits, the idle reaper, and the fan-out to simulator workers.

A session's environments are split into *shards*, one per worker it uses (a 4-env session on
a 2-worker server has 2 + 2), so one step request renders in several processes at once. The
workers' replies are spliced into one msgpack response without decoding the arrays.
"""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import secrets
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from multion.api.live_trail import Trail, extend_trails
from multion.api.paths import allowed_roots, checked_config, checked_options
from multion.api.settings import ServerSettings, replica_of
from multion.api.workers import Reply, Worker, WorkerPool
from multion.config.codec import session_config_from_dict
from multion.task.episode_checks import check_caller_episodes, check_reset_options
from multion.task.errors import BadResetOptionError
from multion.task.memory import ProcessShare, estimate_env_bytes, mib, process_share
from multion_client import errors
from multion_client.constants import ACTIONS_TEXT, action_id
from multion_client.protocol import (
    CreateSession,
    Reset,
    SessionInfo,
    Step,
    decode,
    encode,
    join_encoded,
)

log = logging.getLogger("multion.api")
Answer = TypeVar("Answer")

OBSERVATION_FIELDS = ("observations", "infos")
STEP_FIELDS = ("observations", "rewards", "terminated", "truncated", "infos")


@dataclass
class Shard:
    worker: Worker
    shard_id: str
    start: int
    count: int
    env_bytes: int
    """The memory estimate of each of its environments, reserved on its worker."""
    plain: bool = True
    """A plain session's (not a leaderboard run's): counts against the plain share."""
    closed: bool = False


@dataclass
class Session:
    session_id: str
    num_envs: int
    auto_reset: bool
    shards: list[Shard]
    info: bytes = b""
    """The encoded SessionInfo, the answer to create."""
    renderer: str | None = None
    """What its environments render with (``auto`` resolved by the worker)."""
    last_used: float = field(default_factory=time.monotonic)
    started: bool = False
    done: list[bool] = field(default_factory=list)
    failed: str | None = None
    busy: int = 0
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    owner: str | None = None
    """Who opened a plain session (``team:ID`` or ``ip:ADDRESS``); None for a run's."""
    config: dict[str, Any] = field(default_factory=dict)
    """The config it was created with (the live view finds its episodes with it)."""
    latest: bytes = b""
    """The answer to its last reset or step, which the live view shows (kept only where the
    live view is on)."""
    last_actions: list[int] = field(default_factory=list)
    """The actions of its last step; empty after a reset."""
    trails: list[Trail] = field(default_factory=list)
    """Each environment's path in its episode, which the live view draws (kept as ``latest``)."""


class SessionRegistry:
    """All sessions of a server; every method raises the typed errors of ``multion_client``."""

    def __init__(self, settings: ServerSettings, pool: WorkerPool) -> None:
        self.settings = settings
        self.pool = pool
        self.sessions: dict[str, Session] = {}
        self.reaped = 0
        self.run_reserve = 0.0
        """The share of memory and session slots plain sessions cannot take (set when the
        server runs a challenge: ``settings.run_reserve``)."""
        self._pending_sessions = 0
        self._pending_envs = 0
        self._pending_owners: dict[str, int] = {}
        self.roots = allowed_roots(settings.allowed_dataset_dirs)
        pool.on_death = self._worker_died

    # ------------------------------------------------------------------ operations
    async def create(
        self, message: CreateSession, owner: str | None = None, for_run: bool = False
    ) -> Session:
        """Start the environments of a new session (its ``info`` is the encoded SessionInfo).

        ``owner`` names the client of a plain session (its per-client cap); ``for_run``
        marks a leaderboard run's session, which may use the share kept for runs."""
        # Fail fast, before any worker is involved (a ConfigError is a 422 InvalidConfig).
        config, episodes = session_config_from_dict(message.config)
        env_bytes, share = estimate_env_bytes(config), process_share(config)
        if env_bytes + share.total > self.pool.capacity_bytes:
            need, smaller = f"{mib(env_bytes)} MiB", " or a smaller maps.ego_size"
            if share.total:  # once per worker process, shared by its envs
                need += f" plus {share.describe()} of its worker"
            if share.site_cache:
                smaller = ", a smaller maps.ego_size or a smaller task.goal_site_cache_mib"
            raise errors.InvalidConfig(
                f"one environment of this config may need up to {need}, more than a simulator "
                f"worker of this server may hold ({mib(self.pool.capacity_bytes)} MiB); use "
                f"smaller camera images, a coarser navgrid.cell_size{smaller}"
            )
        # Files the config names are on this server's disk: only allowed directories (403).
        message = dataclasses.replace(message, config=checked_config(message.config, self.roots))
        # After the path check: whether a mesh file exists is told only where it may be read
        # (a BadEpisodeError is a 422 InvalidEpisode).
        check_caller_episodes(episodes or [], config.task, "episodes")
        n, s = message.num_envs, self.settings
        if n > s.max_envs_per_session:
            raise errors.TooManyEnvs(
                f"num_envs={n} is above this server's limit of {s.max_envs_per_session} per session"
            )
        if self.live_sessions() + self._pending_sessions >= s.max_sessions:
            raise errors.TooManySessions(
                f"the server already has {s.max_sessions} sessions (its limit); close one first"
            )
        in_use = self.live_envs() + self._pending_envs
        if in_use + n > s.max_envs_total:
            raise errors.TooManyEnvs(
                f"{n} more environments would exceed the server's limit of {s.max_envs_total} "
                f"({in_use} in use)"
            )
        if not for_run:
            self._check_plain_limits(owner)
        self._pending_sessions += 1
        self._pending_envs += n
        if owner is not None:
            self._pending_owners[owner] = self._pending_owners.get(owner, 0) + 1
        try:
            return await _shielded(self._create(message, env_bytes, share, owner, for_run))
        finally:
            self._pending_sessions -= 1
            self._pending_envs -= n
            if owner is not None:
                self._pending_owners[owner] -= 1
                if not self._pending_owners[owner]:
                    del self._pending_owners[owner]

    def _check_plain_limits(self, owner: str | None) -> None:
        """A plain session may not take a client's share twice, nor the room kept for runs."""
        s = self.settings
        if owner is not None:
            held = sum(1 for x in self.sessions.values() if x.owner == owner and x.failed is None)
            held += self._pending_owners.get(owner, 0)
            if held >= s.sessions_per_client:
                raise errors.TooManySessions(
                    f"this client holds {held} sessions, the most one client may hold "
                    f"(sessions_per_client = {s.sessions_per_client}); close one first"
                )
        if self.run_reserve > 0:
            allowed = int(s.max_sessions * (1 - self.run_reserve))
            plain = sum(1 for x in self.sessions.values() if x.owner is not None) + sum(
                self._pending_owners.values()
            )
            if plain >= allowed:
                raise errors.TooManySessions(
                    f"plain sessions may hold {allowed} of this server's {s.max_sessions} "
                    f"session slots and all are taken; the rest is kept for leaderboard runs "
                    f"(run_reserve = {self.run_reserve})"
                )

    async def reset(self, session_id: str, message: Reset) -> bytes:
        session = self.get(session_id)
        n = session.num_envs
        seeds = message.seeds or [None] * n
        options = checked_options(list(message.options or [None] * n), self.roots)
        if len(seeds) != n or len(options) != n:
            raise errors.BadRequest(
                f"reset needs one seed and one options entry per environment ({n}), "
                f"got {len(seeds)} seeds and {len(options)} options (empty lists mean none)"
            )
        _check_options(options)

        async def run(session: Session) -> bytes:
            session.done = [True] * n  # until the reset succeeds
            payloads = [
                {
                    "seeds": seeds[sh.start : sh.start + sh.count],
                    "options": options[sh.start : sh.start + sh.count],
                }
                for sh in session.shards
            ]
            replies = await self._fan_out(session.shards, "reset", payloads)
            session.started = True
            session.done = [d for header, _ in replies for d in header["done"]]
            return self._keep(session, _splice(OBSERVATION_FIELDS, replies, n), [])

        return await self._run(session, run)

    async def step(self, session_id: str, message: Step) -> bytes:
        session = self.get(session_id)
        actions = _check_actions(message.actions, session.num_envs)

        async def run(session: Session) -> bytes:
            # Refused here, before any worker: a session's envs span workers stepped in
            # parallel, so a worker's refusal would come after the others had stepped. ``done``
            # is what the envs themselves reported (``episode_over``) in the last replies.
            if not session.auto_reset:
                over = [i for i, done in enumerate(session.done) if done]
                if not session.started or over:
                    raise errors.EpisodeOver(
                        "no episode has started; call reset first"
                        if not session.started
                        else f"the episode of environment(s) {over} is over; call reset first "
                        "(or create the session with auto_reset)"
                    )
            payloads = [
                {"actions": actions[sh.start : sh.start + sh.count]} for sh in session.shards
            ]
            replies = await self._fan_out(session.shards, "step", payloads)
            session.done = [d for header, _ in replies for d in header["done"]]
            return self._keep(session, _splice(STEP_FIELDS, replies, session.num_envs), actions)

        return await self._run(session, run)

    def _keep(self, session: Session, answer: bytes, actions: list[int]) -> bytes:
        """``answer``, kept for the live view where it is on (elsewhere it would hold the
        images of every session between its steps)."""
        if self.settings.live_view_on():
            session.latest, session.last_actions = answer, actions
            session.trails = extend_trails(session.trails, answer, reset=not actions)
        return answer

    async def observe(self, session_id: str) -> bytes:
        session = self.get(session_id)

        async def run(session: Session) -> bytes:
            if not session.started:
                raise errors.NotReset("no episode has started in this session; call reset first")
            replies = await self._fan_out(session.shards, "observe", [None] * len(session.shards))
            return _splice(OBSERVATION_FIELDS, replies, session.num_envs)

        return await self._run(session, run)

    async def close(self, session_id: str) -> None:
        """Forget the session and free its environments (also for a failed session)."""
        session = self.sessions.get(session_id)
        if session is None:
            raise errors.SessionNotFound(self._unknown(session_id))
        async with session.lock:
            if self.sessions.pop(session_id, None) is not None:
                await _shielded(self._release(session.shards))

    async def close_all(self) -> None:
        for session_id in list(self.sessions):
            try:
                await self.close(session_id)
            except errors.MultiONError:
                pass  # a worker that is gone holds nothing to free

    # ------------------------------------------------------------------ lookup and limits
    def get(self, session_id: str) -> Session:
        session = self.sessions.get(session_id)
        if session is None:
            raise errors.SessionNotFound(self._unknown(session_id))
        if session.failed is not None:
            raise errors.WorkerFailed(f"session {session_id} is lost: {session.failed}")
        return session

    def live_sessions(self) -> int:
        return sum(1 for s in self.sessions.values() if s.failed is None)

    def live_envs(self) -> int:
        return sum(s.num_envs for s in self.sessions.values() if s.failed is None)

    # ------------------------------------------------------------------ idle reaper
    async def reap_forever(self) -> None:
        interval = max(0.05, min(self.settings.idle_timeout_s / 4, 30.0))
        while True:
            await asyncio.sleep(interval)
            try:
                await self.reap_idle()
            except Exception:  # noqa: BLE001 - the reaper must outlive any one failure
                log.exception("reaping idle sessions failed")

    async def reap_idle(self) -> list[str]:
        """Close the sessions unused for ``idle_timeout_s``; returns their ids."""
        limit = time.monotonic() - self.settings.idle_timeout_s
        idle = [s.session_id for s in self.sessions.values() if s.busy == 0 and s.last_used < limit]
        for session_id in idle:
            log.info(
                "closing session %s: idle for over %s s", session_id, self.settings.idle_timeout_s
            )
            try:
                await self.close(session_id)
            except errors.MultiONError:
                pass
            self.reaped += 1
        return idle

    # ------------------------------------------------------------------ internals
    def _unknown(self, session_id: str) -> str:
        made_by, here = replica_of(session_id), self.settings.replica
        if here is not None and made_by is not None and made_by != here:
            return (
                f"no session {session_id!r} on replica {here!r}: replica {made_by!r} made it, "
                "and a session cannot move between replicas (is that replica down, or does the "
                "proxy not send /v1/sessions/NAME-... to replica NAME?)"
            )
        return f"no session {session_id!r} (never created, closed, or closed after being idle)"

    async def _create(
        self,
        message: CreateSession,
        env_bytes: int,
        share: ProcessShare,
        owner: str | None,
        for_run: bool,
    ) -> Session:
        session_id = self.settings.new_id()  # NAME-<hex> on a named replica
        shards, start = [], 0
        plain_cap = None
        if not for_run and self.run_reserve > 0:
            plain_cap = int(self.pool.capacity_bytes * (1 - self.run_reserve))
        chosen = self.pool.choose(message.num_envs, env_bytes, share, plain_cap)
        for k, (worker, count) in enumerate(chosen):
            shard = Shard(worker, f"{session_id}/{k}", start, count, env_bytes, not for_run)
            shards.append(shard)
            worker.hold(shard.shard_id, count, env_bytes, share, shard.plain)
            start += count
        payload = {"config": message.config, "auto_reset": message.auto_reset}
        payloads = [{**payload, "num_envs": sh.count} for sh in shards]
        try:
            replies = await self._fan_out(shards, "create", payloads)
        except BaseException:
            await self._release(shards)
            raise
        spaces = decode(replies[0][1][0])
        renderer = spaces.pop("renderer", None)
        info = SessionInfo.from_wire(
            {
                "session_id": session_id,
                "num_envs": message.num_envs,
                "auto_reset": message.auto_reset,
                **spaces,
            }
        )
        session = Session(
            session_id, message.num_envs, message.auto_reset, shards,
            done=[True] * message.num_envs, owner=None if for_run else owner or "",
            config=message.config,
        )  # fmt: skip
        session.info, session.renderer = encode(info.to_wire()), renderer
        self.sessions[session_id] = session
        return session

    async def _run(
        self, session: Session, operation: Callable[[Session], Awaitable[bytes]]
    ) -> bytes:
        """Run ``operation`` under the session's lock; it completes even if the client leaves."""

        async def locked() -> bytes:
            async with session.lock:
                if session.session_id not in self.sessions:
                    raise errors.SessionNotFound(self._unknown(session.session_id))
                if session.failed is not None:
                    raise errors.WorkerFailed(
                        f"session {session.session_id} is lost: {session.failed}"
                    )
                session.busy += 1
                try:
                    return await operation(session)
                finally:
                    session.busy -= 1
                    session.last_used = time.monotonic()

        session.last_used = time.monotonic()
        return await _shielded(locked())

    async def _fan_out(self, shards: list[Shard], command: str, payloads: list[Any]) -> list[Reply]:
        """Send one command per shard concurrently; raise the first error once all answered."""
        timeout = self.settings.worker_timeout_s
        requests = [
            sh.worker.request(command, sh.shard_id, p, timeout)
            for sh, p in zip(shards, payloads, strict=True)
        ]
        results: list[Reply | BaseException]
        if len(requests) == 1:  # most sessions: no task for gather to make
            results = [await requests[0]]
        else:
            results = await asyncio.gather(*requests, return_exceptions=True)
        replies: list[Reply] = []
        for sh, result in zip(shards, results, strict=True):
            if isinstance(result, BaseException):
                raise result
            replies.append(result)
            header, _ = result
            if "traceback" in header:
                raise _simulator_bug(header["traceback"], sh.worker)
            if not header["ok"]:
                raise errors.error_from_code(
                    header["code"], header["message"], header.get("status")
                )
        return replies

    async def _release(self, shards: list[Shard]) -> None:
        for shard in shards:
            if shard.closed:
                continue
            shard.closed = True
            shard.worker.release(shard.shard_id, shard.count, shard.env_bytes, shard.plain)
            if shard.worker.alive:
                try:
                    await shard.worker.request(
                        "close", shard.shard_id, None, self.settings.worker_timeout_s
                    )
                except errors.MultiONError:
                    pass  # the worker died meanwhile: nothing left to free

    def _worker_died(self, worker: Worker) -> None:
        log.error("%s", worker.failure)
        for session in self.sessions.values():
            if session.failed is None and any(sh.worker is worker for sh in session.shards):
                session.failed = worker.failure
                _background(self._release(session.shards))


def _check_actions(actions: list[Any], n: int) -> list[int]:
    """Actions as ints, by the in-process env's rules (:func:`action_id`)."""
    if len(actions) != n:
        raise errors.BadRequest(
            f"expected {n} action(s), one per environment of the session, got {len(actions)}"
        )
    checked = []
    for index, action in enumerate(actions):
        value = action_id(action)
        if value is None:
            raise errors.InvalidAction(
                f"illegal action {action!r:.80} for environment {index}; actions are integers: "
                f"{ACTIONS_TEXT}"
            )
        checked.append(value)
    return checked


def _simulator_bug(worker_traceback: str, worker: Worker) -> errors.InternalError:
    """Log a bug in a worker under an incident number; the client gets only that number (the
    exception's text can name files and internals). The session stays open, as the worker
    keeps its environments."""
    incident = secrets.token_hex(4)
    log.error("incident %s: simulator worker %s: %s", incident, worker.pid, worker_traceback)
    return errors.InternalError(
        f"the simulator failed on this request (incident {incident}); retry later"
    )


def _check_options(options: list[Any]) -> None:
    for index, option in enumerate(options):
        try:
            check_reset_options(option or {})
        except BadResetOptionError as error:
            raise errors.BadRequest(f"environment {index}: {error}") from None


def _splice(names: tuple[str, ...], replies: list[Reply], n: int) -> bytes:
    return join_encoded(
        [(name, n, [parts[i] for _, parts in replies]) for i, name in enumerate(names)]
    )


_tasks: set[asyncio.Task[Any]] = set()


def _background(coro: Awaitable[Any]) -> None:
    task = asyncio.ensure_future(coro)
    _tasks.add(task)  # keep a reference until it is done
    task.add_done_callback(_tasks.discard)


async def _shielded(coro: Awaitable[Answer]) -> Answer:
    """Await ``coro`` in its own task: cancelling the caller (a client hanging up) leaves it
    running to the end, so a worker reply is never left for the next request to read."""
    task = asyncio.ensure_future(coro)
    task.add_done_callback(_consume)
    return await asyncio.shield(task)


def _consume(task: asyncio.Task[Any]) -> None:
    if not task.cancelled():
        task.exception()
