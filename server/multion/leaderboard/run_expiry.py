"""Expiry of a run's late episodes and of runs past their time budget: one part of
:class:`~multion.leaderboard.runs.RunService`, which supplies the storage and live-run methods
declared here."""

from __future__ import annotations

import asyncio
import datetime as dt
import logging
from abc import ABC, abstractmethod
from typing import Any

from sqlalchemy import select

from multion.leaderboard.challenge import Challenge
from multion.leaderboard.clock import Clock
from multion.leaderboard.live_run import Lane, LiveRun
from multion.leaderboard.models import Run
from multion.leaderboard.run_store import EpisodeResult
from multion.leaderboard.storage import Database
from multion_client import errors

log = logging.getLogger("multion.leaderboard")
RESTART_GRACE = dt.timedelta(minutes=5)
"""At an orderly stop, the runs in play get this long more on their step budgets: their
clients cannot act while the server restarts."""


class RunExpiry(ABC):
    """Expires late episodes (``step_timeout_s``), too many in a row in a lane
    (``max_consecutive_timeouts``) and runs past ``run_timeout_s``. The storage it needs is
    :class:`~multion.leaderboard.runs.RunService`'s (the abstract methods below)."""

    challenge: Challenge
    clock: Clock
    """What the deadlines are compared with."""
    live: dict[str, LiveRun]
    db: Database

    @abstractmethod
    async def _get_live(self, team_id: int, run_id: str) -> LiveRun: ...

    @abstractmethod
    async def _save(self, live: LiveRun, results: list[EpisodeResult]) -> None: ...

    @abstractmethod
    async def _finish(
        self, live: LiveRun, results: list[EpisodeResult], outcome: str, reason: str | None,
        refunded: bool = False,
    ) -> None: ...  # fmt: skip

    async def expire_forever(self, interval_s: float) -> None:
        """Expire late episodes of running runs, also of clients that never come back."""
        while True:
            await asyncio.sleep(interval_s)
            try:
                await self.expire_all()
            except Exception:  # noqa: BLE001 - the loop must outlive any one failure
                log.exception("expiring runs failed")

    async def expire_all(self) -> None:
        now = self.clock.now()

        def due(session: Any) -> list[tuple[str, int]]:
            rows = session.execute(
                select(Run.id, Run.team_id).where(Run.state == "running", Run.deadline < now)
            ).all()
            return [(r[0], r[1]) for r in rows]

        for run_id, team_id in await self.db.transaction(due):
            try:
                live = await self._get_live(team_id, run_id)
                for lane in live.lanes:
                    async with lane.lock:
                        await self._expire_due(live, lane)
            except errors.MultiONError:
                continue

    async def _expire_due(self, live: LiveRun, lane: Lane) -> None:
        """Score a lane's late episodes as they stand; end the run on too many in a row or
        on its time budget."""
        if live.run_id not in self.live:
            return
        limits, st = self.challenge.limits, lane.state
        now = self.clock.now()
        results: list[EpisodeResult] = []
        if now > live.created_at + dt.timedelta(seconds=limits.run_timeout_s):
            results = [live.result(x, "timeout") for x in live.lanes if x.state.episode_active]
            await self._finish(live, results, "ended", "run_timeout")
            return
        while st.deadline is not None and now > st.deadline:
            if st.episode_active:
                results.append(live.result(lane, "timeout"))
                st.episode_active = False
            elif live.next_position(lane) < live.num_episodes:  # never started in time
                st.position = live.next_position(lane)
                st.seq, st.actions, st.last_metrics = 0, [], None
                results.append(live.result(lane, "timeout"))
            st.consecutive_timeouts += 1
            st.deadline += dt.timedelta(seconds=limits.step_timeout_s)
            if live.all_done:
                await self._finish(live, results, "finished", None)
                return
            if st.consecutive_timeouts >= limits.max_consecutive_timeouts:
                results += [
                    live.result(x, "run_ended")
                    for x in live.lanes
                    if x is not lane and x.state.episode_active
                ]
                await self._finish(live, results, "ended", "timeouts")
                return
            if live.lane_done(lane):
                st.deadline = None  # this lane is through; the others go on
        if results:
            lane.last_answer = None
            await self._save(live, results)

    async def grant_restart_grace(self) -> None:
        """At an orderly stop: every lane of the runs in play may wait until
        :data:`RESTART_GRACE` and a step budget from now, saved (so a replica that carries a
        run on sees it too), and a restart that takes minutes costs no episode a timeout."""
        step = dt.timedelta(seconds=self.challenge.limits.step_timeout_s)
        later = self.clock.now() + RESTART_GRACE + step
        for live in list(self.live.values()):
            try:  # bounded: a stop must not wait on a stuck lane
                await asyncio.wait_for(self._extend(live, later), 5.0)
            except errors.MultiONError:
                continue  # ended meanwhile, or moved to another replica
            except Exception:  # noqa: BLE001 - the stop goes on; the saved deadlines stand
                log.exception("run %s: no restart grace", live.run_id)

    async def _extend(self, live: LiveRun, later: dt.datetime) -> None:
        held = []
        try:
            for lane in live.lanes:  # in lane order, as everywhere: no deadlock
                await lane.lock.acquire()
                held.append(lane)
            for lane in live.lanes:
                if lane.state.deadline is not None:
                    lane.state.deadline = max(lane.state.deadline, later)
            await self._save(live, [])
        finally:
            for lane in held:
                lane.lock.release()
