"""A running run as one server process holds it: its episodes, config, lanes and sessions.

A run plays ``num_envs`` episodes at once, one per *lane*; lane k plays the run's episodes k,
k + K, k + 2K … in the run's order, each through its own one-environment session, with its
own sequence numbers and step budget. One lane is the plain case: a run plays its episodes
one after the other.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import time
from dataclasses import dataclass, field
from typing import Any

from multion.config.episode import Episode
from multion.leaderboard.challenge import Phase, Track
from multion.leaderboard.hidden import RunDraw
from multion.leaderboard.models import Run
from multion.leaderboard.results import missed_metrics
from multion.leaderboard.run_store import EpisodeResult, LaneState, RunState


@dataclass
class Lane:
    """One lane of a live run: its state, session and last answer."""

    index: int
    state: LaneState
    episode: Episode | None = None
    """The lane's current (or last started) episode, once drawn."""
    session_id: str | None = None
    last_answer: bytes | None = None
    last_end_reason: str | None = None
    episode_clock: float = field(default_factory=time.monotonic)
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    """Held while the lane acts (lanes act at once; the run's row is written under
    ``LiveRun.save_lock``)."""


@dataclass
class LiveRun:
    """A running run held by this server process."""

    run_id: str
    team_id: int
    track: Track
    phase: Phase
    draw: RunDraw
    """Which hidden episodes the run plays."""
    episode_ids: list[str]
    """The ids of its episodes in play order (known before fresh ones are drawn)."""
    config: dict[str, Any]
    """The environment config, without episodes (each is given when it starts)."""
    created_at: dt.datetime
    version: int
    """The row's version (compare-and-set at every save)."""
    lanes: list[Lane]
    save_lock: asyncio.Lock = field(default_factory=asyncio.Lock)

    @classmethod
    def of(cls, row: Run, track: Track, phase: Phase, episode_ids: list[str]) -> LiveRun:
        """The live form of a stored run (``episode_ids``: its episodes' ids in play order)."""
        state = RunState.of(row)
        return cls(
            run_id=row.id,
            team_id=row.team_id,
            track=track,
            phase=phase,
            draw=draw_of(row),
            episode_ids=episode_ids,
            config=track.env_config(phase, tuple(row.sensors), row.maps),
            created_at=row.created_at,
            version=state.version,
            lanes=[Lane(k, lane) for k, lane in enumerate(state.lanes)],
        )

    @property
    def num_episodes(self) -> int:
        return len(self.draw.order)

    def lane_of(self, position: int) -> Lane:
        """The lane that plays episode ``position``."""
        return self.lanes[position % len(self.lanes)]

    def next_position(self, lane: Lane) -> int:
        """The run-order number of the lane's next episode (≥ num_episodes: none left)."""
        st = lane.state
        return lane.index if st.position < 0 else st.position + len(self.lanes)

    def lane_done(self, lane: Lane) -> bool:
        return not lane.state.episode_active and self.next_position(lane) >= self.num_episodes

    @property
    def all_done(self) -> bool:
        return all(self.lane_done(lane) for lane in self.lanes)

    def run_state(self) -> RunState:
        return RunState(self.version, [lane.state for lane in self.lanes])

    def result(self, lane: Lane, end_reason: str) -> EpisodeResult:
        """The lane's current episode's result as it stands, ended for ``end_reason``."""
        st = lane.state
        lane.last_end_reason = end_reason
        metrics = st.last_metrics or missed_metrics(self.track.num_goals, end_reason)
        return EpisodeResult(
            position=st.position,
            episode_index=self.draw.order[st.position],
            episode_id=self.episode_ids[st.position],
            end_reason=end_reason,
            metrics=metrics,
            actions="".join(str(a) for a in st.actions),
            seconds=time.monotonic() - lane.episode_clock if st.actions else 0.0,
        )


def draw_of(row: Run) -> RunDraw:
    """Which hidden episodes a stored run plays."""
    return RunDraw(row.id, row.episode_set, tuple(row.order))
