"""What a run asks for, checked against the challenge before anything is created: its track
and phase, the sensors the track allows, the oracle maps' options, a valid environment config."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from multion.config.codec import ConfigError, session_config_from_dict
from multion.leaderboard.challenge import Challenge, Phase, Track
from multion_client import errors
from multion_client.run_protocol import CreateRun


@dataclass(frozen=True)
class RunRequest:
    """A checked :class:`CreateRun`."""

    track: Track
    phase: Phase
    sensors: tuple[str, ...]
    config: dict[str, Any]
    """The run's environment config (no episodes yet)."""
    num_envs: int
    """Lanes: episodes played at once."""


def track_phase(challenge: Challenge, track_name: str, phase_name: str) -> tuple[Track, Phase]:
    """The named track and phase; 404 ``unknown_track`` naming the valid ones."""
    track = challenge.track(track_name)
    if track is None:
        names = [t.name for t in challenge.tracks]
        raise errors.UnknownTrack(f"no track {track_name!r}; tracks are {names}")
    phase = track.phase(phase_name)
    if phase is None:
        names = [p.name for p in track.phases]
        raise errors.UnknownTrack(
            f"track {track_name!r} has no phase {phase_name!r}; phases are {names}"
        )
    return track, phase


def checked_request(challenge: Challenge, message: CreateRun) -> RunRequest:
    """``message`` checked: 404 for an unknown track or phase, 403 for a sensor or maps the
    track does not allow, 422 for a config the environment refuses."""
    track, phase = track_phase(challenge, message.track, message.phase)
    most = min(challenge.limits.max_envs_per_run, phase.episodes)
    if not 1 <= message.num_envs <= most:
        raise errors.InvalidConfig(
            f"num_envs = {message.num_envs} is out of range: allowed an integer in [1, {most}] "
            f"(the challenge's max_envs_per_run is {challenge.limits.max_envs_per_run}, the "
            f"phase has {phase.episodes} episodes)"
        )
    sensors = tuple(message.sensors or track.allowed_sensors)
    refused = [s for s in sensors if s not in track.allowed_sensors]
    if refused:
        raise errors.NotAllowedInRun(
            f"track {track.name!r} ({track.kind}) does not allow sensor(s) {refused}; it "
            f"allows {list(track.allowed_sensors)}"
        )
    if message.maps and not {"oracle_map", "oracle_ego_map"} & set(track.allowed_sensors):
        raise errors.NotAllowedInRun(f"track {track.name!r} has no oracle maps to configure")
    config = track.env_config(phase, sensors, message.maps)
    try:
        session_config_from_dict(config)
    except ConfigError as error:
        raise errors.InvalidConfig(str(error)) from None
    return RunRequest(track, phase, sensors, config, message.num_envs)
