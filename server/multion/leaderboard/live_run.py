"""A running run as one server process holds it: its episodes, config, state and session."""

from __future__ import annotations

import asyncio
import datetime as dt
import time
from dataclasses import dataclass, field
from typing import Any

from multion.leaderboard.challenge import Phase, Track
from multion.leaderboard.hidden import RunDraw
from multion.leaderboard.models import Run
from multion.leaderboard.results import missed_metrics
from multion.leaderboard.run_store import EpisodeResult, RunState
from multion.task.episode import Episode


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
    state: RunState
    episode: Episode | None = None
    """The current (or last started) episode, once drawn."""
    session_id: str | None = None
    last_answer: bytes | None = None
    last_end_reason: str | None = None
    episode_clock: float = field(default_factory=time.monotonic)
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)

    @classmethod
    def of(cls, row: Run, track: Track, phase: Phase, episode_ids: list[str]) -> LiveRun:
        """The live form of a stored run (``episode_ids``: its episodes' ids in play order)."""
        return cls(
            run_id=row.id,
            team_id=row.team_id,
            track=track,
            phase=phase,
            draw=draw_of(row),
            episode_ids=episode_ids,
            config=track.env_config(phase, tuple(row.sensors), row.maps),
            created_at=row.created_at,
            state=RunState.of(row),
        )

    def result(self, end_reason: str) -> EpisodeResult:
        """The current episode's result as it stands, ended for ``end_reason``."""
        st = self.state
        self.last_end_reason = end_reason
        metrics = st.last_metrics or missed_metrics(self.track.num_goals, end_reason)
        return EpisodeResult(
            position=st.position,
            episode_index=self.draw.order[st.position],
            episode_id=self.episode_ids[st.position],
            end_reason=end_reason,
            metrics=metrics,
            actions="".join(str(a) for a in st.actions),
            seconds=time.monotonic() - self.episode_clock if st.actions else 0.0,
        )


def draw_of(row: Run) -> RunDraw:
    """Which hidden episodes a stored run plays."""
    return RunDraw(row.id, row.episode_set, tuple(row.order))
