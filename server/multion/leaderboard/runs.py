"""The run service: a team's run of hidden episodes, played through a one-environment session.

A run holds a session of the server's ordinary :class:`SessionRegistry` whose episodes are the
phase's hidden ones in the run's own shuffled order; the service alone resets and steps it,
strips everything the track does not allow from the answers (episode and scene ids, rewards,
per-step metrics), and saves the run's state in the database at every step (its actions so
far, the last metrics, the deadline). So:

* a repeated ``(episode, seq)`` returns the stored answer without acting twice;
* a run whose session is gone (server restart, idle reaper, another replica) is rebuilt by
  replaying the current episode's saved actions, which is exact (the simulator is
  deterministic), and resumes at the same step;
* a late action or episode start expires the episode as it stands (``step_timeout_s``);
  ``max_consecutive_timeouts`` in a row, or ``run_timeout_s`` in all, end the run, and its
  missing episodes count as failures;
* a simulator worker that dies fails the run and refunds it.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import logging
import time
from collections import OrderedDict
from typing import Any

from sqlalchemy import select

from multion.api.sessions import SessionRegistry
from multion.leaderboard.challenge import Challenge
from multion.leaderboard.hidden import HiddenEpisodes, RunDraw, run_order
from multion.leaderboard.live_run import LiveRun, draw_of
from multion.leaderboard.models import Run, utcnow
from multion.leaderboard.run_request import checked_request, track_phase
from multion.leaderboard.run_store import (
    EpisodeResult,
    RunMoved,
    create_run,
    describe_run,
    finish_run,
    save_state,
)
from multion.leaderboard.storage import Database
from multion.task.episode import Episode
from multion_client import errors
from multion_client.protocol import (
    CreateRun,
    CreateSession,
    Reset,
    RunInfo,
    RunObservation,
    RunStatus,
    StartEpisode,
    Step,
    decode,
    encode,
    space_from_wire,
)

log = logging.getLogger("multion.leaderboard")
ENDED_KEPT = 256
KNOWN_END_REASONS = ("max_steps", "timeout")
"""End reasons a participant knows anyway (it counted its steps, it was late): the only ones
sent on phases without per-episode feedback (success vs wrong_found would leak results)."""


class RunService:
    """Every run operation; raises the typed errors of ``multion_client.errors``."""

    def __init__(self, challenge: Challenge, db: Database, registry: SessionRegistry) -> None:
        self.challenge = challenge
        self.db = db
        self.registry = registry
        self.hidden = HiddenEpisodes(challenge)
        self.live: dict[str, LiveRun] = {}
        self._creating = asyncio.Lock()  # one quota check at a time in this process
        self.ended: OrderedDict[str, LiveRun] = OrderedDict()
        """Recently ended runs, so a retry of a run's last step still gets its answer."""

    # ------------------------------------------------------------------ create
    async def create(self, team_id: int, message: CreateRun) -> RunInfo:
        """Start a run (the quota is debited here); runs of the team ``baselines`` are marked
        baselines by :func:`run_store.create_run`."""
        request = checked_request(self.challenge, message)
        track, phase, sensors = request.track, request.phase, request.sensors
        run_id = self.registry.settings.new_id()  # NAME-<hex> on a named replica, ≤ 32
        if phase.episode_set == "fixed":
            fixed = await asyncio.to_thread(self.hidden.phase_set, track, phase)
            order = run_order(self.challenge, run_id, len(fixed))
        else:
            order = list(range(phase.episodes))
        draw = RunDraw(run_id, phase.episode_set, tuple(order))
        episode_ids = await asyncio.to_thread(self.hidden.episode_ids, track, phase, draw)
        first = await asyncio.to_thread(self.hidden.episode, track, phase, draw, 0)
        row = Run(
            id=run_id,
            team_id=team_id,
            track=track.name,
            phase=phase.name,
            method=message.method,
            paper_url=message.paper_url,
            code_url=message.code_url,
            sensors=list(sensors),
            maps=dict(message.maps or {}),
            episode_set=phase.episode_set,
            order=order,
            created_at=utcnow(),
            deadline=utcnow() + dt.timedelta(seconds=self.challenge.limits.step_timeout_s),
        )
        async with self._creating:
            await self._db(lambda s: create_run(s, row, track, phase, row.created_at))
        live = LiveRun.of(row, track, phase, episode_ids)
        live.episode = first
        self.live[run_id] = live
        async with live.lock:
            info = await self._open_session(live)
            # the first step budget starts now, with the run ready (opening took a while)
            live.state.deadline = self._deadline()
            await self._save(live, [])
        limits = self.challenge.describe()["limits"]
        return RunInfo(
            run_id=run_id,
            track=track.name,
            phase=phase.name,
            num_episodes=len(order),
            sensors=list(sensors),
            observation_space=info["observation_space"],
            action_space=info["action_space"],
            limits=limits,
        )

    # ------------------------------------------------------------------ play
    async def start_episode(self, team_id: int, run_id: str, message: StartEpisode) -> bytes:
        live = await self._get_live(team_id, run_id)
        async with live.lock:
            await self._expire_due(live)
            st = live.state
            if message.episode == st.position and st.episode_active and live.last_answer:
                return live.last_answer  # a retry: the episode has started already
            await self._check_running(live)
            if st.episode_active:
                raise errors.EpisodeInProgress(
                    f"episode {st.position} is still going (step {st.seq}); a run plays its "
                    "episodes one after the other, each to its end"
                )
            if message.episode != st.position + 1:
                raise errors.SequenceMismatch(
                    f"the next episode of this run is {st.position + 1}, not {message.episode}"
                )
            episode = await self._draw(live, st.position + 1)
            reply = await self._session_call(live, "reset", episode)
            observation, info = reply["observations"][0], reply["infos"][0]
            live.episode = episode
            st.position += 1
            st.episode_active, st.seq, st.actions = True, 0, []
            st.last_metrics = info["metrics"]
            st.deadline = self._deadline()
            st.consecutive_timeouts = 0
            live.episode_clock = time.monotonic()
            await self._save(live, [])
            answer = RunObservation(st.position, 0, observation, done=False)
            live.last_answer = encode(answer.to_wire())
            return live.last_answer

    async def step(self, team_id: int, run_id: str, episode: int, seq: int, action: int) -> bytes:
        live = await self._get_live(team_id, run_id)
        async with live.lock:
            st = live.state
            if (episode, seq) == (st.position, st.seq) and seq > 0:
                if live.last_answer is None and st.episode_active:
                    await self._rebuild(live)  # after a restart: replay to the same step
                if live.last_answer is not None:
                    return live.last_answer  # a retry of the last step: do not act twice
            await self._expire_due(live)
            await self._check_running(live)
            if not st.episode_active and episode == st.position:
                why = self._shown_reason(live, live.last_end_reason)
                raise errors.EpisodeOver(
                    f"episode {episode} has ended{f' ({why})' if why else ''}; start episode "
                    f"{episode + 1} (POST episodes)"
                )
            if not st.episode_active or episode != st.position or seq != st.seq + 1:
                expected = (
                    f"episode {st.position}, seq {st.seq + 1}"
                    if st.episode_active
                    else f"no step: start episode {st.position + 1} first"
                )
                raise errors.SequenceMismatch(
                    f"got episode {episode}, seq {seq}; expected {expected}"
                )
            if not 0 <= action <= 3:
                raise errors.InvalidAction(f"illegal action {action!r}; actions are 0..3")
            # Saved after the step, before the answer (saving while the simulator steps was
            # measured slower: the threads contend for the GIL and the cores).
            reply = await self._session_call(live, "step", action)
            observation, info = reply["observations"][0], reply["infos"][0]
            done = bool(reply["terminated"][0] or reply["truncated"][0])
            st.seq += 1
            st.actions.append(action)
            st.last_metrics = info["metrics"]
            st.deadline = self._deadline()
            return await self._conclude(live, observation, done)

    async def observe(self, team_id: int, run_id: str) -> bytes:
        """Where the run stands: the last answer (for a client resuming after a crash)."""
        live = await self._get_live(team_id, run_id)
        async with live.lock:
            await self._expire_due(live)
            if live.last_answer is None and live.state.episode_active:
                await self._rebuild(live)  # after a restart: replay to the same step
            if live.last_answer is not None and live.state.episode_active:
                return live.last_answer
            st = live.state
            answer = RunObservation(
                st.position, st.seq, {}, done=True, run_done=live.run_id not in self.live
            )
            return encode(answer.to_wire())

    async def abandon(self, team_id: int, run_id: str) -> RunStatus:
        """End a run now: its missing episodes count as failures (the quota stays used)."""
        live = await self._get_live(team_id, run_id)
        async with live.lock:
            await self._check_running(live)
            results = [live.result("abandoned")] if live.state.episode_active else []
            await self._finish(live, results, "ended", "abandoned")
        return await self.status(team_id, run_id)

    # ------------------------------------------------------------------ status
    async def status(self, team_id: int | None, run_id: str) -> RunStatus:
        live = self.live.get(run_id)
        if live is not None and (team_id is None or live.team_id == team_id):
            async with live.lock:
                await self._expire_due(live)

        def read(session: Any) -> RunStatus:
            run = session.get(Run, run_id)
            if run is None or (team_id is not None and run.team_id != team_id):
                raise errors.RunNotFound(f"no run {run_id!r} for this team")
            return describe_run(session, self.challenge, run)

        return await self._db(read)

    async def list_runs(self, team_id: int) -> list[RunStatus]:
        def read(session: Any) -> list[RunStatus]:
            runs = session.scalars(
                select(Run).where(Run.team_id == team_id).order_by(Run.created_at.desc())
            ).all()
            return [describe_run(session, self.challenge, run, episodes=False) for run in runs]

        return await self._db(read)

    # ------------------------------------------------------------------ expiry
    async def expire_forever(self, interval_s: float) -> None:
        """Expire late episodes of running runs, also of clients that never come back."""
        while True:
            await asyncio.sleep(interval_s)
            try:
                await self.expire_all()
            except Exception:  # noqa: BLE001 - the loop must outlive any one failure
                log.exception("expiring runs failed")

    async def expire_all(self) -> None:
        now = utcnow()

        def due(session: Any) -> list[tuple[str, int]]:
            rows = session.execute(
                select(Run.id, Run.team_id).where(Run.state == "running", Run.deadline < now)
            ).all()
            return [(r[0], r[1]) for r in rows]

        for run_id, team_id in await self._db(due):
            try:
                live = await self._get_live(team_id, run_id)
                async with live.lock:
                    await self._expire_due(live)
            except errors.MultiONError:
                continue

    async def _expire_due(self, live: LiveRun) -> None:
        """Score late episodes as they stand; end the run on too many or on its time budget."""
        if live.run_id not in self.live:
            return
        limits, st = self.challenge.limits, live.state
        now = utcnow()
        results: list[EpisodeResult] = []
        if now > live.created_at + dt.timedelta(seconds=limits.run_timeout_s):
            if st.episode_active:
                results.append(live.result("timeout"))
            await self._finish(live, results, "ended", "run_timeout")
            return
        while st.deadline is not None and now > st.deadline:
            if st.episode_active:
                results.append(live.result("timeout"))
                st.episode_active = False
            elif st.position + 1 < len(live.draw.order):  # the next episode was never started
                st.position += 1
                st.seq, st.actions, st.last_metrics = 0, [], None
                results.append(live.result("timeout"))
            st.consecutive_timeouts += 1
            st.deadline += dt.timedelta(seconds=limits.step_timeout_s)
            if st.position == len(live.draw.order) - 1 and not st.episode_active:
                await self._finish(live, results, "finished", None)
                return
            if st.consecutive_timeouts >= limits.max_consecutive_timeouts:
                await self._finish(live, results, "ended", "timeouts")
                return
        if results:
            live.last_answer = None
            await self._save(live, results)

    # ------------------------------------------------------------------ internals
    async def _get_live(self, team_id: int, run_id: str) -> LiveRun:
        live = self.live.get(run_id) or self.ended.get(run_id)
        if live is not None:
            if live.team_id != team_id:
                raise errors.RunNotFound(f"no run {run_id!r} for this team")
            return live
        row = await self._db(lambda s: s.get(Run, run_id))
        if row is None or row.team_id != team_id:
            raise errors.RunNotFound(f"no run {run_id!r} for this team")
        if row.state != "running":
            raise errors.RunOver(_over(row.state, row.end_reason))
        track, phase = track_phase(self.challenge, row.track, row.phase)
        episode_ids = await asyncio.to_thread(self.hidden.episode_ids, track, phase, draw_of(row))
        live = self.live.setdefault(run_id, LiveRun.of(row, track, phase, episode_ids))
        return live

    async def _check_running(self, live: LiveRun) -> None:
        if live.run_id not in self.live:
            row = await self._db(lambda s: s.get(Run, live.run_id))
            raise errors.RunOver(_over(row.state, row.end_reason) if row else "the run is over")

    async def _draw(self, live: LiveRun, position: int) -> Episode:
        """The episode the run plays at ``position`` (a fresh one is drawn now)."""
        return await asyncio.to_thread(
            self.hidden.episode, live.track, live.phase, live.draw, position
        )

    async def _open_session(self, live: LiveRun) -> dict[str, Any]:
        """Create the run's session; on a server fault the run fails and is refunded."""
        if live.episode is None:  # the config needs an episode; each reset names its own
            live.episode = await self._draw(live, max(live.state.position, 0))
        config = {**live.config, "episodes": [live.episode.to_dict()]}
        try:
            answer = await self.registry.create(CreateSession(config, 1, False), for_run=True)
        except (errors.WorkerFailed, errors.LimitExceeded, errors.InternalError) as error:
            log.error("run %s: no session: %s", live.run_id, error.message)
            await self._finish(live, [], "failed", "server_error", refunded=True)
            why = "has no room for" if isinstance(error, errors.LimitExceeded) else "failed in"
            raise type(error)(
                f"the server {why} this run's simulator; the run is over and refunded (it does "
                "not count against your quota): retry later"
            ) from None
        info = decode(answer)
        live.session_id = info["session_id"]
        return {k: space_from_wire(info[k]) for k in ("observation_space", "action_space")}

    async def _session_call(self, live: LiveRun, verb: str, argument: Episode | int) -> Any:
        """Reset (argument: the episode) or step (argument: the action) the run's environment,
        rebuilding the session first if it is gone (restart, idle reaper, another replica)."""
        for attempt in range(2):
            try:
                if live.session_id is None:
                    await self._rebuild(live)
                assert live.session_id is not None
                if isinstance(argument, Episode):
                    options = [{"episode": argument.to_dict()}]
                    reply = await self.registry.reset(live.session_id, Reset([None], options))
                else:
                    reply = await self.registry.step(live.session_id, Step([argument]))
                return decode(reply)
            except errors.SessionNotFound:
                live.session_id = None
                if attempt == 1:
                    raise
            except (errors.WorkerFailed, errors.InternalError) as error:
                log.error("run %s: the simulator failed: %s", live.run_id, error.message)
                await self._close_session(live)
                await self._finish(live, [], "failed", "server_error", refunded=True)
                raise errors.WorkerFailed(
                    "the simulator failed during this run; the run is over and refunded: it "
                    "does not count against your quota, and shows no results"
                ) from None
        raise AssertionError("unreachable")

    async def _rebuild(self, live: LiveRun) -> None:
        """A new session in the run's state: the current episode reset and its actions replayed."""
        await self._close_session(live)
        st = live.state
        if st.episode_active and live.episode is None:
            live.episode = await self._draw(live, st.position)
        await self._open_session(live)
        if not st.episode_active or live.session_id is None:
            return
        assert live.episode is not None
        options = [{"episode": live.episode.to_dict()}]
        reply = decode(await self.registry.reset(live.session_id, Reset([None], options)))
        done = False
        for action in st.actions:
            reply = decode(await self.registry.step(live.session_id, Step([action])))
            done = bool(reply["terminated"][0] or reply["truncated"][0])
        st.last_metrics = reply["infos"][0]["metrics"]
        # the state is as saved, unless (defensively) its last action ended the episode unrecorded
        await self._conclude(live, reply["observations"][0], done, save_unfinished=False)

    def _shown_reason(self, live: LiveRun, end_reason: str | None) -> str | None:
        """What the participant may learn of why an episode ended (see KNOWN_END_REASONS)."""
        if live.phase.feedback == "episodes" or end_reason in KNOWN_END_REASONS:
            return end_reason
        return None

    async def _conclude(
        self, live: LiveRun, observation: Any, done: bool, save_unfinished: bool = True
    ) -> bytes:
        """After a step (or a replay up to it): record the episode if it ended, finish the run
        if that was its last episode, else save the state; keep the answer for retries."""
        st = live.state
        end_reason = st.last_metrics.get("end_reason") if done and st.last_metrics else None
        results = []
        if done:
            st.episode_active = False
            results.append(live.result(str(end_reason)))
        run_done = done and st.position == len(live.draw.order) - 1
        if run_done:
            await self._finish(live, results, "finished", None)
        elif done or save_unfinished:
            await self._save(live, results)
        metrics = st.last_metrics if done and live.phase.feedback == "episodes" else None
        answer = RunObservation(
            st.position, st.seq, observation, done=done,
            end_reason=self._shown_reason(live, end_reason), metrics=metrics, run_done=run_done,
        )  # fmt: skip
        live.last_answer = encode(answer.to_wire())
        return live.last_answer

    async def _save(self, live: LiveRun, results: list[EpisodeResult]) -> None:
        def save() -> None:
            if results:
                with self.db.sessions.begin() as session:
                    save_state(session, live.run_id, live.state, results)
            else:  # the per-step save: one UPDATE on a bare connection, no ORM session
                with self.db.engine.begin() as connection:
                    save_state(connection, live.run_id, live.state, results)

        try:
            await asyncio.to_thread(save)
        except RunMoved:
            self.live.pop(live.run_id, None)
            await self._close_session(live)
            raise errors.SequenceMismatch(
                "this run was changed elsewhere (another server replica or an organiser); "
                "GET its observe route and continue from there"
            ) from None

    async def _finish(
        self,
        live: LiveRun,
        results: list[EpisodeResult],
        outcome: str,
        reason: str | None,
        refunded: bool = False,
    ) -> None:
        await self._db(
            lambda s: finish_run(
                s,
                live.run_id,
                live.state,
                results,
                outcome,
                reason,
                live.track,
                live.episode_ids,
                list(live.draw.order),
                refunded,
            )
        )
        self.live.pop(live.run_id, None)
        self.ended[live.run_id] = live
        while len(self.ended) > ENDED_KEPT:
            self.ended.popitem(last=False)
        await self._close_session(live)

    async def _close_session(self, live: LiveRun) -> None:
        if live.session_id is not None:
            with contextlib.suppress(errors.MultiONError):
                await self.registry.close(live.session_id)
            live.session_id = None

    def _deadline(self) -> dt.datetime:
        return utcnow() + dt.timedelta(seconds=self.challenge.limits.step_timeout_s)

    async def _db(self, work: Any) -> Any:
        """Run ``work(session)`` in a thread, in one transaction."""

        def run() -> Any:
            with self.db.sessions.begin() as session:
                return work(session)

        return await asyncio.to_thread(run)

    async def close(self) -> None:
        for live in list(self.live.values()):
            await self._close_session(live)
        self.hidden.close()


def _over(state: str, reason: str | None) -> str:
    return f"the run is over ({state}{', ' + reason if reason else ''})"
