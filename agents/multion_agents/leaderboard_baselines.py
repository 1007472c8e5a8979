"""``multion leaderboard baselines``: the non-learned agents played through the run protocol.

They play as the organisers' team ``baselines`` (created if needed, with a fresh token that is
revoked afterwards), over HTTP like any participant, so their runs go through the same checks,
expiry and scoring; runs of that team are marked baselines and have no quota.
"""

from __future__ import annotations

from collections.abc import Sequence

from multion.leaderboard.challenge import Challenge, Track
from multion.leaderboard.run_store import BASELINE_TEAM
from multion.leaderboard.storage import Database, add_team, add_token, find_team, revoke_tokens

BASELINE_AGENTS = ("random", "random-oracle-found", "explorer", "oracle-planner")


def agents_for(track: Track, names: Sequence[str] | None = None) -> list[str]:
    """The baselines whose sensors the track allows (``random-oracle-found`` needs
    ``goal_distance``, ``oracle-planner`` the oracle map)."""
    from multion_agents.registry import agent_class

    chosen = []
    for name in names or BASELINE_AGENTS:
        cls = agent_class(name)
        if set(cls.sensors) <= set(track.allowed_sensors):
            chosen.append(name)
    return chosen


def baseline_token(db: Database) -> str:
    with db.sessions.begin() as session:
        try:
            return add_token(session, find_team(session, BASELINE_TEAM))
        except ValueError:
            return add_team(session, BASELINE_TEAM)[1]


def play_baselines(
    db: Database,
    challenge: Challenge,
    server: str,
    tracks: Sequence[str] | None = None,
    phases: Sequence[str] | None = None,
    agents: Sequence[str] | None = None,
    progress: bool = True,
) -> list[str]:
    """Play the baselines on every (track, phase) selected; returns the run ids."""
    from multion_agents.cli_submit import oracle_maps, play_run
    from multion_agents.registry import agent_class
    from multion_client.run import RunEnv

    token = baseline_token(db)
    run_ids = []
    try:
        for track in challenge.tracks:
            if tracks and track.name not in tracks:
                continue
            for phase in track.phases:
                if phases and phase.name not in phases:
                    continue
                for name in agents_for(track, agents):
                    cls = agent_class(name)
                    env = RunEnv(
                        server, track.name, phase.name, name, token=token,
                        sensors=list(cls.sensors), maps=oracle_maps(cls),
                    )  # fmt: skip
                    if progress:
                        print(f"{track.name}/{phase.name}: {name} (run {env.run_id})")
                    play_run(env, cls, 0, None, progress)
                    status = env.status()
                    env.close()
                    run_ids.append(env.run_id)
                    if progress and status.results:
                        value = status.results[track.metric]["mean"]
                        print(f"  {status.state}: {track.metric} {100 * value:.1f}%")
    finally:
        with db.sessions.begin() as session:
            revoke_tokens(session, find_team(session, BASELINE_TEAM))
    return run_ids
