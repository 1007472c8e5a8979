"""The run service: a team's run of hidden episodes, played through one-environment sessions.

A run plays its phase's hidden episodes (its own fresh ones, or the phase's fixed set in its
own order) in ``num_envs`` lanes at once (lane k: episodes k, k + K …; one lane: one after the
other). Each lane holds a session of the server's ordinary :class:`SessionRegistry` that the
service alone resets and steps (:mod:`lane_sessions`); answers are stripped of everything the
track does not allow (episode and scene ids, rewards, per-step metrics), and the run's state
is saved in the database at every step (each lane's actions so far, last metrics, deadline).
So:

* a repeated ``(episode, seq)`` returns the stored answer without acting twice;
* a lane whose session is gone (server restart, idle reaper, another replica) is rebuilt by
  replaying its episode's saved actions, which is exact, and resumes at the same step;
* a late action or episode start expires the lane's episode as it stands
  (``step_timeout_s``); ``max_consecutive_timeouts`` in a row in a lane, or ``run_timeout_s``
  in all, end the run, and its missing episodes count as failures;
* a simulator worker that dies fails the run and refunds it.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import logging
import time
from collections import OrderedDict
from typing import Any, NoReturn

from sqlalchemy import select

from multion.api.sessions import SessionRegistry
from multion.config.episode import Episode
from multion.leaderboard.challenge import Challenge
from multion.leaderboard.clock import Clock, SystemClock
from multion.leaderboard.hidden import HiddenEpisodes, RunDraw, run_order
from multion.leaderboard.lane_sessions import LaneSessions, ServerFault, with_observation
from multion.leaderboard.live_run import Lane, LiveRun, draw_of
from multion.leaderboard.models import Run
from multion.leaderboard.run_expiry import RunExpiry
from multion.leaderboard.run_request import checked_request, track_phase
from multion.leaderboard.run_store import (
    EpisodeResult,
    LaneState,
    RunMoved,
    RunState,
    create_run,
    describe_run,
    finish_run,
    refuse_over_quota,
    save_state,
)
from multion.leaderboard.storage import Database
from multion_client import errors
from multion_client.protocol import encode
from multion_client.run_protocol import CreateRun, RunInfo, RunObservation, RunStatus, StartEpisode

log = logging.getLogger("multion.leaderboard")
ENDED_KEPT = 256
STOPPING = (
    "the server is stopping (a restart): retry in a minute; the run goes on where it was, "
    "nothing is lost"
)
REFUNDED = (
    "the server failed during this run (its log says why); the run is over and refunded: it "
    "does not count against your quota"
)
KNOWN_END_REASONS = ("max_steps", "timeout")
"""End reasons a participant knows anyway (it counted its steps, it was late): the only ones
sent on phases without per-episode feedback (success vs wrong_found would leak results)."""


class RunService(RunExpiry):
    """Every run operation; raises the typed errors of ``multion_client.errors``. Deadlines
    follow ``clock`` (None: the wall clock; a test's ``ManualClock`` moves without sleeping)."""

    def __init__(
        self, challenge: Challenge, db: Database, registry: SessionRegistry,
        clock: Clock | None = None,
    ) -> None:  # fmt: skip
        self.challenge = challenge
        self.clock: Clock = clock or SystemClock()
        self.db = db
        self.registry = registry
        self.hidden = HiddenEpisodes(challenge)
        self.sessions = LaneSessions(registry, self.hidden)
        self.live: dict[str, LiveRun] = {}
        self._creating = asyncio.Lock()  # one quota check at a time in this process
        self.ended: OrderedDict[str, LiveRun] = OrderedDict()
        """Recently ended runs, so a retry of a run's last step still gets its answer."""
        self.stopping = False

    # ------------------------------------------------------------------ create
    async def create(self, team_id: int, message: CreateRun) -> RunInfo:
        """Start a run (the quota is debited here); runs of the team ``baselines`` are marked
        baselines by :func:`run_store.create_run`."""
        request = checked_request(self.challenge, message)
        track, phase, sensors = request.track, request.phase, request.sensors
        run_id = self.registry.settings.new_id()  # NAME-<hex> on a named replica, ≤ 32
        try:  # nothing is charged yet: a failure here is a plain error to retry
            if phase.episode_set == "fixed":
                fixed = await asyncio.to_thread(self.hidden.phase_set, track, phase)
                order = run_order(self.challenge, run_id, len(fixed))
            else:
                order = list(range(phase.episodes))
            draw = RunDraw(run_id, phase.episode_set, tuple(order))
            episode_ids = await asyncio.to_thread(self.hidden.episode_ids, track, phase, draw)
            firsts = [
                await asyncio.to_thread(self.hidden.episode, track, phase, draw, k)
                for k in range(request.num_envs)
            ]
        except Exception:
            log.exception("preparing a new run's episodes on %s/%s failed", track.name, phase.name)
            raise errors.InternalError(
                "the server failed to prepare this run's episodes; no run was created and "
                "nothing counts against your quota: retry later"
            ) from None
        state = RunState(0, [LaneState(deadline=self._deadline()) for _ in firsts])
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
            num_envs=request.num_envs,
            created_at=self.clock.now(),
            version=state.version,  # read by LiveRun.of before the insert
            **state.columns(),
        )
        live = LiveRun.of(row, track, phase, episode_ids)
        for lane, first in zip(live.lanes, firsts, strict=True):
            lane.episode = first
        # Refused before the run exists (over quota, no room in the simulator now): the
        # organiser's records hold only runs whose id their participant was given.
        now = row.created_at
        await self.db.transaction(lambda s: refuse_over_quota(s, team_id, track, phase, now))
        spaces = await self.sessions.open_new(live)
        try:
            async with self._creating:
                await self.db.transaction(lambda s: create_run(s, row, track, phase, now))
        except BaseException:
            await self.sessions.close_all(live)
            raise
        self.live[run_id] = live
        try:
            for lane in live.lanes:  # the first step budgets start now, with every lane ready
                lane.state.deadline = self._deadline()
            await self._save(live, [])
        except errors.MultiONError:
            raise
        except Exception:  # the quota was debited: the server's failure refunds it
            log.exception("opening run %s failed", run_id)
            await self._fail(live, ServerFault(errors.InternalError(REFUNDED)), stopping=False)
        limits = self.challenge.describe()["limits"]
        return RunInfo(
            run_id=run_id,
            track=track.name,
            phase=phase.name,
            num_episodes=len(order),
            sensors=list(sensors),
            observation_space=spaces[0]["observation_space"],
            action_space=spaces[0]["action_space"],
            limits=limits,
            num_envs=request.num_envs,
        )

    # ------------------------------------------------------------------ play
    async def start_episode(self, team_id: int, run_id: str, message: StartEpisode) -> bytes:
        live = await self._get_live(team_id, run_id)
        lane = self._lane(live, message.episode)
        async with lane.lock:
            await self._expire_due(live, lane)
            st = lane.state
            if message.episode == st.position and st.episode_active and lane.last_answer:
                return lane.last_answer  # a retry: the episode has started already
            await self._check_running(live)
            where = f" of lane {lane.index}" if len(live.lanes) > 1 else ""
            if st.episode_active:
                raise errors.EpisodeInProgress(
                    f"episode {st.position}{where} is still going (step {st.seq}); a run plays "
                    "its episodes one after the other in each lane, each to its end"
                )
            if message.episode != live.next_position(lane):
                raise errors.SequenceMismatch(
                    f"the next episode{where} is {live.next_position(lane)}, not "
                    f"{message.episode} (the server chooses the episodes)"
                )
            try:
                episode = await self.sessions.draw(live, message.episode)
            except ServerFault as fault:
                await self._fail(live, fault)
            reply = await self._session_call(live, lane, episode)
            observation, info = reply["observations"][0], reply["infos"][0]
            lane.episode = episode
            st.position = message.episode
            st.episode_active, st.seq, st.actions = True, 0, []
            st.last_metrics = info["metrics"]
            st.deadline = self._deadline()
            st.consecutive_timeouts = 0
            lane.episode_clock = time.monotonic()
            await self._save(live, [])
            lane.last_answer = with_observation(
                RunObservation(st.position, 0, {}, done=False), observation
            )
            return lane.last_answer

    async def step(self, team_id: int, run_id: str, episode: int, seq: int, action: int) -> bytes:
        live = await self._get_live(team_id, run_id)
        lane = self._lane(live, episode)
        async with lane.lock:
            st = lane.state
            if (episode, seq) == (st.position, st.seq) and seq > 0:
                if lane.last_answer is None and st.episode_active:
                    await self._rebuild(live, lane)  # after a restart: replay to the same step
                if lane.last_answer is not None:
                    return lane.last_answer  # a retry of the last step: do not act twice
            await self._expire_due(live, lane)
            await self._check_running(live)
            if not st.episode_active and episode == st.position:
                why = self._shown_reason(live, lane.last_end_reason)
                raise errors.EpisodeOver(
                    f"episode {episode} has ended{f' ({why})' if why else ''}; start episode "
                    f"{live.next_position(lane)} (POST episodes)"
                )
            if not st.episode_active or episode != st.position or seq != st.seq + 1:
                expected = (
                    f"episode {st.position}, seq {st.seq + 1}"
                    if st.episode_active
                    else f"no step: start episode {live.next_position(lane)} first"
                )
                raise errors.SequenceMismatch(
                    f"got episode {episode}, seq {seq}; expected {expected}"
                )
            if not 0 <= action <= 3:
                raise errors.InvalidAction(f"illegal action {action!r}; actions are 0..3")
            # Saved after the step, before the answer (saving while the simulator steps was
            # measured slower: the threads contend for the GIL and the cores).
            reply = await self._session_call(live, lane, action)
            observation, info = reply["observations"][0], reply["infos"][0]
            done = bool(reply["terminated"][0] or reply["truncated"][0])
            st.seq += 1
            st.actions.append(action)
            st.last_metrics = info["metrics"]
            st.deadline = self._deadline()
            return await self._conclude(live, lane, observation, done)

    async def observe(self, team_id: int, run_id: str, lane_index: int = 0) -> bytes:
        """Where a lane stands: its last answer (for a client resuming after a crash)."""
        live = await self._get_live(team_id, run_id)
        if not 0 <= lane_index < len(live.lanes):
            raise errors.BadRequest(
                f"lane {lane_index} is out of range: this run has lanes 0..{len(live.lanes) - 1}"
            )
        lane = live.lanes[lane_index]
        async with lane.lock:
            await self._expire_due(live, lane)
            if lane.last_answer is None and lane.state.episode_active:
                await self._rebuild(live, lane)  # after a restart: replay to the same step
            if lane.last_answer is not None and lane.state.episode_active:
                return lane.last_answer
            st = lane.state
            answer = RunObservation(
                st.position, st.seq, {}, done=True, run_done=live.run_id not in self.live
            )
            return encode(answer.to_wire())

    async def abandon(self, team_id: int, run_id: str) -> RunStatus:
        """End a run now: its missing episodes count as failures (the quota stays used)."""
        live = await self._get_live(team_id, run_id)
        for lane in live.lanes:  # in lane order, as everywhere: no deadlock
            await lane.lock.acquire()
        try:
            await self._check_running(live)
            results = [
                live.result(lane, "abandoned") for lane in live.lanes if lane.state.episode_active
            ]
            await self._finish(live, results, "ended", "abandoned")
        finally:
            for lane in live.lanes:
                lane.lock.release()
        return await self.status(team_id, run_id)

    # ------------------------------------------------------------------ status
    async def status(self, team_id: int | None, run_id: str) -> RunStatus:
        live = self.live.get(run_id)
        if live is not None and (team_id is None or live.team_id == team_id):
            for lane in live.lanes:
                async with lane.lock:
                    with contextlib.suppress(errors.RunOver):  # another lane ended it
                        await self._expire_due(live, lane)

        def read(session: Any) -> RunStatus:
            run = session.get(Run, run_id)
            if run is None or (team_id is not None and run.team_id != team_id):
                raise errors.RunNotFound(f"no run {run_id!r} for this team")
            return describe_run(session, self.challenge, run)

        return await self.db.transaction(read)

    async def list_runs(self, team_id: int) -> list[RunStatus]:
        def read(session: Any) -> list[RunStatus]:
            runs = session.scalars(
                select(Run).where(Run.team_id == team_id).order_by(Run.created_at.desc())
            ).all()
            return [describe_run(session, self.challenge, run, episodes=False) for run in runs]

        return await self.db.transaction(read)

    # ------------------------------------------------------------------ internals
    def _lane(self, live: LiveRun, episode: int) -> Lane:
        if not 0 <= episode < live.num_episodes:
            raise errors.SequenceMismatch(
                f"episode {episode} is out of range: this run has episodes "
                f"0..{live.num_episodes - 1}"
            )
        return live.lane_of(episode)

    async def _get_live(self, team_id: int, run_id: str) -> LiveRun:
        live = self.live.get(run_id) or self.ended.get(run_id)
        if live is not None:
            if live.team_id != team_id:
                raise errors.RunNotFound(f"no run {run_id!r} for this team")
            return live
        row = await self.db.transaction(lambda s: s.get(Run, run_id))
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
            row = await self.db.transaction(lambda s: s.get(Run, live.run_id))
            if row is None or row.state == "running":  # its end is being written
                raise errors.RunOver("the run is over")
            raise errors.RunOver(_over(row.state, row.end_reason))

    async def _session_call(self, live: LiveRun, lane: Lane, argument: Episode | int) -> Any:
        """Reset (argument: the episode) or step (argument: the action) a lane's environment,
        rebuilding its session first if it is gone (restart, idle reaper, another replica)."""
        for attempt in range(2):
            try:
                if lane.session_id is None:
                    await self._rebuild(live, lane)
                return await self.sessions.call(live, lane, argument)
            except errors.SessionNotFound:
                lane.session_id = None
                if attempt == 1:
                    raise
            except ServerFault as fault:
                await self._fail(live, fault)
        raise AssertionError("unreachable")

    async def _rebuild(self, live: LiveRun, lane: Lane) -> None:
        """A new session in the lane's state, its episode replayed to the saved step."""
        try:
            replayed = await self.sessions.replay(live, lane)
        except ServerFault as fault:
            await self._fail(live, fault)
        if replayed is not None:
            # the state is as saved, unless (defensively) its last action ended the episode
            await self._conclude(live, lane, *replayed, save_unfinished=False)

    async def _fail(
        self, live: LiveRun, fault: ServerFault, stopping: bool | None = None
    ) -> NoReturn:
        """The server broke the run: it fails and is refunded (never charged), unless the
        server is stopping in order: then it stays as saved, to go on after the restart."""
        if self.stopping if stopping is None else stopping:
            raise errors.WorkerFailed(STOPPING) from None
        await self._finish(live, [], "failed", "server_error", refunded=True)
        raise fault.error from None

    def _shown_reason(self, live: LiveRun, end_reason: str | None) -> str | None:
        """What the participant may learn of why an episode ended (see KNOWN_END_REASONS)."""
        if live.phase.feedback == "episodes" or end_reason in KNOWN_END_REASONS:
            return end_reason
        return None

    async def _conclude(
        self,
        live: LiveRun,
        lane: Lane,
        observation: bytes,
        done: bool,
        save_unfinished: bool = True,
    ) -> bytes:
        """After a step (or a replay up to it): record the episode if it ended, finish the run
        if that was its last, else save the state; keep the answer for retries."""
        st = lane.state
        end_reason = st.last_metrics.get("end_reason") if done and st.last_metrics else None
        results = []
        if done:
            st.episode_active = False
            results.append(live.result(lane, str(end_reason)))
            if live.lane_done(lane):
                st.deadline = None  # this lane is through; the others go on
        run_done = done and live.all_done
        if run_done:
            await self._finish(live, results, "finished", None)
        elif done or save_unfinished:
            await self._save(live, results)
        metrics = st.last_metrics if done and live.phase.feedback == "episodes" else None
        answer = RunObservation(
            st.position, st.seq, {}, done=done,
            end_reason=self._shown_reason(live, end_reason), metrics=metrics, run_done=run_done,
        )  # fmt: skip
        lane.last_answer = with_observation(answer, observation)
        return lane.last_answer

    async def _save(self, live: LiveRun, results: list[EpisodeResult]) -> None:
        async with live.save_lock:  # lanes act at once; their saves take turns
            await self._check_running(live)  # another lane may have ended the run meanwhile
            state = live.run_state()

            def save() -> None:
                if results:
                    with self.db.sessions.begin() as session:
                        save_state(session, live.run_id, state, results)
                else:  # the per-step save: one UPDATE on a bare connection, no ORM session
                    with self.db.engine.begin() as connection:
                        save_state(connection, live.run_id, state, results)

            try:
                await asyncio.to_thread(save)
            except RunMoved:
                self.live.pop(live.run_id, None)
                for lane in live.lanes:
                    await self.sessions.close(lane)
                raise errors.SequenceMismatch(
                    "this run was changed elsewhere (another server replica or an organiser); "
                    "GET its observe route and continue from there"
                ) from None
            live.version = state.version

    async def _finish(
        self,
        live: LiveRun,
        results: list[EpisodeResult],
        outcome: str,
        reason: str | None,
        refunded: bool = False,
    ) -> None:
        async with live.save_lock:
            if live.run_id not in self.live:
                return  # another lane ended it meanwhile
            for lane in live.lanes:  # every episode still going is in ``results``
                lane.state.episode_active, lane.state.deadline = False, None
            state = live.run_state()
            # over for every lane from now on, while the database is written
            self.live.pop(live.run_id, None)
            self.ended[live.run_id] = live
            try:
                await self.db.transaction(
                    lambda s: finish_run(
                        s,
                        live.run_id,
                        state,
                        results,
                        outcome,
                        reason,
                        live.track,
                        live.episode_ids,
                        list(live.draw.order),
                        refunded,
                    )
                )
            except RunMoved:  # another replica ended it first: its record stands
                for lane in live.lanes:
                    await self.sessions.close(lane)
                raise errors.RunOver("the run is over (ended by another server replica)") from None
            live.version = state.version
        while len(self.ended) > ENDED_KEPT:
            self.ended.popitem(last=False)
        for lane in live.lanes:
            await self.sessions.close(lane)

    def _deadline(self) -> dt.datetime:
        return self.clock.now() + dt.timedelta(seconds=self.challenge.limits.step_timeout_s)

    async def close(self) -> None:
        self.stopping = True  # what fails from now on is the stop, not the runs' fault
        await self.grant_restart_grace()
        for live in list(self.live.values()):
            for lane in live.lanes:
                await self.sessions.close(lane)
        self.hidden.close()


def _over(state: str, reason: str | None) -> str:
    return f"the run is over ({state}{', ' + reason if reason else ''})"
