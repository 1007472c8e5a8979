"""The simulator side of a run's lanes: each lane's one-environment session in the server's
ordinary :class:`SessionRegistry`, its episodes drawn from the hidden ones and given inline at
each reset, and its rebuild (a new session, the episode reset and its saved actions replayed:
exact, the simulator is deterministic) after a restart, the idle reaper or another replica."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any

from multion.api.sessions import SessionRegistry
from multion.config.episode import Episode
from multion.leaderboard.hidden import HiddenEpisodes
from multion.leaderboard.live_run import Lane, LiveRun
from multion_client import errors
from multion_client.protocol import CreateSession, Reset, Step, decode, space_from_wire
from multion_client.run_protocol import RunObservation
from multion_client.wire import decode_keeping_encoded, encode_with_encoded

log = logging.getLogger("multion.leaderboard")


class ServerFault(Exception):
    """The simulator failed (or had no room) for a lane: the run must fail and be refunded.
    ``error`` is what the participant is told (no internal ids)."""

    def __init__(self, error: errors.MultiONError) -> None:
        super().__init__(error.message)
        self.error = error


class LaneSessions:
    """Opening, stepping, replaying and closing lane sessions; raises :class:`ServerFault`."""

    def __init__(self, registry: SessionRegistry, hidden: HiddenEpisodes) -> None:
        self.registry = registry
        self.hidden = hidden

    async def draw(self, live: LiveRun, position: int) -> Episode:
        """The episode the run plays at ``position`` (a fresh one is drawn now)."""
        try:
            return await asyncio.to_thread(
                self.hidden.episode, live.track, live.phase, live.draw, position
            )
        except Exception:  # the hidden-episode helper failed twice: the server's fault
            log.exception("run %s: drawing episode %d failed", live.run_id, position)
            raise ServerFault(
                errors.InternalError(
                    "the server failed to prepare this run's next episode (its log says why); "
                    "the run is over and refunded: it does not count against your quota"
                )
            ) from None

    async def open(self, live: LiveRun, lane: Lane) -> dict[str, Any]:
        """Create the lane's session; returns the observation and action spaces."""
        if lane.episode is None:  # the config needs an episode; each reset names its own
            lane.episode = await self.draw(live, max(lane.state.position, lane.index))
        config = {**live.config, "episodes": [lane.episode.to_dict()]}
        try:
            session = await self.registry.create(CreateSession(config, 1, False), for_run=True)
        except (errors.WorkerFailed, errors.LimitExceeded, errors.InternalError) as error:
            log.error("run %s lane %d: no session: %s", live.run_id, lane.index, error.message)
            why = "has no room for" if isinstance(error, errors.LimitExceeded) else "failed in"
            raise ServerFault(
                type(error)(
                    f"the server {why} this run's simulator; the run is over and refunded (it "
                    "does not count against your quota): retry later"
                )
            ) from None
        info = decode(session.info)
        lane.session_id = info["session_id"]
        return {k: space_from_wire(info[k]) for k in ("observation_space", "action_space")}

    async def open_new(self, live: LiveRun) -> list[dict[str, Any]]:
        """Open every lane of a run that is not created yet (no row, no quota debited): on a
        refusal (no room now) or a fault the lanes opened are closed again and the error says
        that no run was created, so no run exists that its participant never learned of."""
        try:
            return [await self.open(live, lane) for lane in live.lanes]
        except ServerFault as fault:
            await self.close_all(live)
            why = (
                "has no room for" if isinstance(fault.error, errors.LimitExceeded) else "failed in"
            )
            raise type(fault.error)(
                f"the server {why} this run's simulator now; no run was created and nothing "
                "counts against your quota: retry later"
            ) from None
        except BaseException:
            await self.close_all(live)
            raise

    async def close_all(self, live: LiveRun) -> None:
        for lane in live.lanes:
            await self.close(lane)

    async def call(self, live: LiveRun, lane: Lane, argument: Episode | int) -> dict[str, Any]:
        """Reset the lane's environment into ``argument`` (an episode) or step it (an action):
        the decoded answer, whose ``observations`` stay encoded (they go on to the participant
        as they are). The session must exist; ``errors.SessionNotFound`` says it is gone."""
        assert lane.session_id is not None
        try:
            if isinstance(argument, Episode):
                options: list[dict[str, Any] | None] = [{"episode": argument.to_dict()}]
                reply = await self.registry.reset(lane.session_id, Reset([None], options))
            else:
                reply = await self.registry.step(lane.session_id, Step([argument]))
        except (errors.WorkerFailed, errors.InternalError) as error:
            log.error("run %s lane %d: the simulator failed: %s", live.run_id, lane.index,
                      error.message)  # fmt: skip
            await self.close(lane)
            raise ServerFault(
                errors.WorkerFailed(
                    "the simulator failed during this run; the run is over and refunded: it "
                    "does not count against your quota, and shows no results"
                )
            ) from None
        return decode_keeping_encoded(reply, "observations")

    async def replay(self, live: LiveRun, lane: Lane) -> tuple[bytes, bool] | None:
        """A new session in the lane's state: its episode reset and its actions replayed.
        Returns the last (encoded observation, done), or None when no episode is going."""
        await self.close(lane)
        st = lane.state
        if st.episode_active and lane.episode is None:
            lane.episode = await self.draw(live, st.position)
        await self.open(live, lane)
        if not st.episode_active:
            return None
        assert lane.episode is not None
        reply = await self.call(live, lane, lane.episode)
        done = False
        for action in st.actions:
            reply = await self.call(live, lane, action)
            done = bool(reply["terminated"][0] or reply["truncated"][0])
        st.last_metrics = reply["infos"][0]["metrics"]
        return reply["observations"][0], done

    async def close(self, lane: Lane) -> None:
        if lane.session_id is not None:
            with contextlib.suppress(errors.MultiONError):
                await self.registry.close(lane.session_id)
            lane.session_id = None


def with_observation(answer: RunObservation, observation: bytes) -> bytes:
    """``answer`` encoded with ``observation``, the simulator's encoding of it (not decoded
    and encoded again: a 256² RGB-D observation is ~460 kB)."""
    return encode_with_encoded(answer.to_wire(), {"observation": observation})
