"""``multion leaderboard baselines``: the non-learned agents played through the run protocol.

They play as the organisers' team ``baselines`` (created if needed, with a fresh token that is
revoked afterwards), over HTTP like any participant, so their runs go through the same checks,
expiry and scoring; runs of that team are marked baselines and have no quota. The tracks and
phases are the server's own (``GET /v1/challenge``), so no challenge file is needed here.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from multion.config.ranges import ConfigError
from multion.leaderboard.run_store import BASELINE_TEAM
from multion.leaderboard.storage import (
    Database,
    StorageError,
    add_team,
    add_token,
    find_team,
    revoke_tokens,
)
from multion_agents.agent import AgentError
from multion_agents.cli_submit import oracle_maps, play_run, run_config
from multion_agents.registry import agent_class
from multion_client.client import Client
from multion_client.errors import Unauthorized
from multion_client.run import RunEnv

BASELINE_AGENTS = ("random", "random-oracle-found", "explorer", "oracle-planner")


def agents_for(allowed_sensors: Sequence[str], names: Sequence[str] | None = None) -> list[str]:
    """The baselines whose sensors the track allows (``random-oracle-found`` needs
    ``goal_distance``, ``oracle-planner`` the oracle map)."""
    return [
        name
        for name in names or BASELINE_AGENTS
        if set(agent_class(name).sensors) <= set(allowed_sensors)
    ]


def baseline_token(db: Database) -> str:
    with db.sessions.begin() as session:
        try:
            return add_token(session, find_team(session, BASELINE_TEAM))
        except StorageError:
            return add_team(session, BASELINE_TEAM)[1]


def server_tracks(server: str) -> list[dict[str, Any]]:
    """The tracks the server hosts (name, sensors, metric, phases)."""
    client = Client(server)
    try:
        return list(client.challenge()["tracks"])
    finally:
        client.close()


def play_baselines(
    db: Database,
    server: str,
    tracks: Sequence[str] | None = None,
    phases: Sequence[str] | None = None,
    agents: Sequence[str] | None = None,
    progress: bool = True,
) -> list[str]:
    """Play the baselines on every (track, phase) of the server selected; returns the run ids.

    ``db`` must be the server's own database: the token is written there."""
    hosted = server_tracks(server)
    unknown = sorted(set(tracks or ()) - {t["name"] for t in hosted})
    if unknown:
        raise ConfigError(
            f"--track {', '.join(unknown)}: the server has {[t['name'] for t in hosted]}"
        )
    selected = [t for t in hosted if not tracks or t["name"] in tracks]
    known_phases = sorted({p["name"] for t in selected for p in t["phases"]})
    missing = sorted(set(phases or ()) - set(known_phases))
    if missing:
        raise ConfigError(f"--phase {', '.join(missing)}: the server's phases are {known_phases}")
    token = baseline_token(db)
    run_ids = []
    try:
        for track in hosted:
            if tracks and track["name"] not in tracks:
                continue
            for phase in track["phases"]:
                if phases and phase["name"] not in phases:
                    continue
                for name in agents_for(track["sensors"], agents):
                    cls = agent_class(name)
                    config = run_config(cls, track)
                    try:  # before the run is created: a refused agent costs no quota
                        cls(seed=0).configure(config)
                    except AgentError as error:
                        print(f"{track['name']}/{phase['name']}: {name} skipped: {error}")
                        continue
                    # said before the run is created: the server may first build the phase's
                    # hidden episodes, which can take a minute
                    print(f"{track['name']}/{phase['name']}: {name}", end="", flush=True)
                    try:
                        env = RunEnv(
                            server, track["name"], phase["name"], name, token=token,
                            sensors=list(cls.sensors), maps=oracle_maps(cls),
                        )  # fmt: skip
                    except Unauthorized:
                        print(flush=True)  # end the line begun above
                        raise StorageError(
                            f"{server} refused the baselines' token: the token was written to "
                            f"{db.engine.url.render_as_string(hide_password=True)}, which is not "
                            "that server's database (give the server's --database, or set "
                            "MULTION_LEADERBOARD_DATABASE as for `multion serve`)"
                        ) from None
                    # Each run's start and end are said even with --quiet (which only drops
                    # the progress bar): a run can take minutes.
                    print(f" (run {env.run_id})", flush=True)
                    play_run(env, cls, 0, None, progress, config=config)
                    status = env.status()
                    env.close()
                    run_ids.append(env.run_id)
                    score = ""
                    if status.results:
                        value = status.results[track["metric"]]["mean"]
                        score = f": {track['metric']} {100 * value:.1f}%"
                    print(f"  {status.state}{score}", flush=True)
    finally:
        with db.sessions.begin() as session:
            revoke_tokens(session, find_team(session, BASELINE_TEAM))
    return run_ids
