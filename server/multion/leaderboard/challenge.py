"""The challenge definition: tracks, phases, hidden scenes and time budgets, from one TOML file.

An organiser writes one file (see ``docs/leaderboard.md``)::

    [challenge]
    name = "MultiON 2026"
    secret_env = "MULTION_CHALLENGE_SECRET"   # or: secret = "..." (keep the file private)

    [limits]
    step_timeout_s = 60          # an episode whose next action is this late ends as it stands
    max_consecutive_timeouts = 3 # that many expired episodes in a row end the run
    run_timeout_s = 86400        # a run still going after this long ends
    max_envs_per_run = 4         # episodes a run may play at once (lanes)

    [hidden]                     # optional; default: the packaged houses' generator (8–16 rooms)
    rooms = [8, 12]              # narrow the room count range, within [1, 16]

    [[tracks]]
    name = "3-on"
    num_goals = 3
    kind = "standard"            # rgb, depth, goal, goal_onehot, gps, compass
    camera = { width = 256, height = 256 }

    [[tracks.phases]]
    name = "minival"
    episodes = 30
    houses = 2
    feedback = "episodes"        # per-episode results to the team
    daily_quota = 20
    episodes_per_run = "fixed"   # or "fresh" (the default of aggregate and sealed phases)

Every value is checked when the file is read (:func:`multion.leaderboard.challenge_file.
load_challenge`); :class:`ChallengeError` names the field and the allowed range. The config
classes are frozen dataclasses, one per section, with their ranges.
"""

from __future__ import annotations

import datetime as dt
import re
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

from multion.config.codec import ConfigError, env_config_from_dict
from multion.config.errors import UsageError
from multion.config.sensors import SENSORS, sensors_with_access
from multion.scenes.registry import HOUSE_CONFIG, MAX_SIZED_ROOMS

STANDARD_SENSORS = sensors_with_access(("standard",))
"""What a *standard* track may receive (the MultiON challenge's sensors): no privileged one."""
ORACLE_SENSORS = sensors_with_access(("standard", "oracle"))
"""What an *oracle* track may receive: the standard sensors and the oracle ones (the oracle maps
and the oracle goal distance); training-only sensors (``goal_mask``) go to no track."""
TRACK_KINDS = {"standard": STANDARD_SENSORS, "oracle": ORACLE_SENSORS}
METRICS = ("ppl", "progress", "success", "spl")
FEEDBACK = ("episodes", "aggregate", "sealed")
"""What a team sees of its finished runs: per-episode records and aggregates (minival),
aggregates only (test-standard), nothing until ``sealed_until`` (test-challenge)."""
EPISODE_SETS = ("fresh", "fixed")
"""Which episodes a run plays: its own, drawn for it from the secret and its id (``fresh``), or
the phase's one set in a per-run order (``fixed``: paired comparisons, but a team can learn the
episodes in one run and replay what it learned in the next)."""
MIN_SECRET_CHARS = 16
_NAME = re.compile(r"[a-z0-9][a-z0-9._-]{0,39}")


class ChallengeError(UsageError, ValueError):
    """A challenge file that cannot be used; the message names the field and the problem."""


@dataclass(frozen=True)
class Limits:
    """Time budgets of a run (organiser settings)."""

    step_timeout_s: float = 60.0
    """(0, 86400]: an episode whose next action (or start) is later ends as it stands."""
    max_consecutive_timeouts: int = 3
    """[1, 1000]: that many expired episodes in a row end the run."""
    run_timeout_s: float = 86400.0
    """(0, 30 days]: a run still going after this long ends; its missing episodes fail."""
    max_envs_per_run: int = 4
    """[1, 64]: the most episodes a run may play at once (``CreateRun.num_envs``); each takes
    a simulator environment while it plays."""

    def __post_init__(self) -> None:
        _check_range("limits.step_timeout_s", self.step_timeout_s, 0.0, 86400.0, low_open=True)
        _check_range("limits.max_consecutive_timeouts", self.max_consecutive_timeouts, 1, 1000)
        _check_range("limits.run_timeout_s", self.run_timeout_s, 0.0, 30 * 86400.0, low_open=True)
        _check_range("limits.max_envs_per_run", self.max_envs_per_run, 1, 64)


@dataclass(frozen=True)
class HiddenScenes:
    """The generator of the hidden houses (their numbers come from the secret)."""

    rooms: tuple[int, int] | None = None
    """None: the packaged houses' own distribution (the generator draws 8–16 rooms, the
    calibrated benchmark); else [low, high] in [1, 16], a narrower room count range (houses
    under 8 rooms are easier than val: ``multion leaderboard check --generate`` says by how
    much)."""

    def __post_init__(self) -> None:
        if self.rooms is None:
            return
        low, high = self.rooms
        _check_range("hidden.rooms[0]", low, 1, MAX_SIZED_ROOMS)
        _check_range("hidden.rooms[1]", high, low, MAX_SIZED_ROOMS)

    @property
    def room_range(self) -> tuple[int, int]:
        """The room counts hidden houses may have."""
        return self.rooms or (HOUSE_CONFIG.min_rooms, HOUSE_CONFIG.max_rooms)


@dataclass(frozen=True)
class Phase:
    """One phase of a track, in the Habitat challenge's manner."""

    name: str
    episodes: int
    """[1, 100000] hidden episodes played by every run of this phase."""
    houses: int = 3
    """[1, 1000] hidden houses the episodes are spread over."""
    feedback: str = "aggregate"
    daily_quota: int | None = None
    """Runs a team may create in any 24 hours (None: no daily cap)."""
    total_quota: int | None = None
    """Runs a team may create in this phase, ever (None: no cap)."""
    sealed_until: dt.datetime | None = None
    """With feedback "sealed": results become visible to teams from this UTC time on."""
    max_steps: int | None = None
    """[1, 100000] the episode step limit, if not the track's."""
    episodes_per_run: str | None = None
    """``fresh`` or ``fixed`` (see :data:`EPISODE_SETS`); None: ``fixed`` on phases with
    per-episode feedback, ``fresh`` on aggregate and sealed phases."""

    def __post_init__(self) -> None:
        where = f"phase {self.name!r}"
        _check_name(f"{where}: name", self.name)
        _check_range(f"{where}: episodes", self.episodes, 1, 100_000)
        _check_range(f"{where}: houses", self.houses, 1, 1000)
        if self.feedback not in FEEDBACK:
            raise ChallengeError(
                f"{where}: feedback must be one of {FEEDBACK}, got {self.feedback!r}"
            )
        for quota in ("daily_quota", "total_quota"):
            value = getattr(self, quota)
            if value is not None:
                _check_range(f"{where}: {quota}", value, 0, 1_000_000)
        if (self.feedback == "sealed") != (self.sealed_until is not None):
            raise ChallengeError(
                f"{where}: feedback 'sealed' needs sealed_until (a UTC date-time) and only it does"
            )
        if self.max_steps is not None:
            _check_range(f"{where}: max_steps", self.max_steps, 1, 100_000)
        if self.episodes_per_run is not None and self.episodes_per_run not in EPISODE_SETS:
            raise ChallengeError(
                f"{where}: episodes_per_run must be one of {EPISODE_SETS}, got "
                f"{self.episodes_per_run!r}"
            )

    @property
    def episode_set(self) -> str:
        """``fresh`` or ``fixed``: what the phase's new runs play."""
        if self.episodes_per_run is not None:
            return self.episodes_per_run
        return "fixed" if self.feedback == "episodes" else "fresh"

    def results_visible(self, now: dt.datetime) -> bool:
        return self.sealed_until is None or now >= self.sealed_until


@dataclass(frozen=True)
class Track:
    """A task (m goals), the sensors a participant may receive, the camera and the ranking."""

    name: str
    num_goals: int
    kind: str = "standard"
    sensors: tuple[str, ...] = ()
    """The allowed sensors; empty: those of ``kind``."""
    camera: Mapping[str, Any] = field(default_factory=dict)
    """CameraConfig fields (width, height, hfov_deg …); the rest keep their defaults."""
    maps: Mapping[str, Any] = field(default_factory=dict)
    """MapConfig fields for the oracle maps; a run on an oracle track may choose its own."""
    max_steps: int = 2500
    metric: str = "ppl"
    """The ranking metric: ppl (the MultiON challenge's), progress, success or spl."""
    num_distractors: int = 0
    """Distractor objects per episode (``task.num_distractors``, 0..8 - num_goals; the MultiON
    2.0 tracks have some)."""
    success_distance: float = 1.5
    """FOUND succeeds within this geodesic distance, metres (the paper's 1.5; MultiON 2.0: 1.0)."""
    found_budget: int = 0
    """Wrong FOUNDs allowed before one ends the episode (``task.found_budget``)."""
    goal_set: str = "colours"
    """``colours`` (cylinders), ``shapes`` or ``objects`` (everyday objects)."""
    phases: tuple[Phase, ...] = ()

    def __post_init__(self) -> None:
        where = f"track {self.name!r}"
        _check_name(f"{where}: name", self.name)
        _check_range(f"{where}: num_goals", self.num_goals, 1, 8)
        if self.kind not in TRACK_KINDS:
            raise ChallengeError(
                f"{where}: kind must be one of {list(TRACK_KINDS)}, got {self.kind!r}"
            )
        unknown = [s for s in self.sensors if s not in SENSORS]
        if unknown:
            raise ChallengeError(
                f"{where}: unknown sensor(s) {unknown}; sensors are {list(SENSORS)}"
            )
        beyond_kind = [s for s in self.sensors if s not in TRACK_KINDS[self.kind]]
        if beyond_kind:  # a standard track lists no privileged sensor, no track a training one
            raise ChallengeError(
                f"{where}: sensor(s) {beyond_kind} are not for a {self.kind} track; "
                f"a {self.kind} track may receive {list(TRACK_KINDS[self.kind])}"
            )
        if self.metric not in METRICS:
            raise ChallengeError(f"{where}: metric must be one of {METRICS}, got {self.metric!r}")
        _check_range(f"{where}: max_steps", self.max_steps, 1, 100_000)
        if not self.phases:
            raise ChallengeError(f"{where}: needs at least one [[tracks.phases]]")
        names = [p.name for p in self.phases]
        if len(set(names)) != len(names):
            raise ChallengeError(f"{where}: phase names repeat: {names}")
        try:
            env_config_from_dict(self.env_config(self.phases[0]))
        except ConfigError as error:
            raise ChallengeError(f"{where}: {error}") from None

    @property
    def rules(self) -> dict[str, Any]:
        """The task rules a track may set beside m and the step limit (TaskConfig fields)."""
        return {
            "num_distractors": self.num_distractors,
            "success_distance": self.success_distance,
            "found_budget": self.found_budget,
            "goal_set": self.goal_set,
        }

    @property
    def map_config(self) -> dict[str, Any]:
        """The oracle maps' settings of a run that chooses none (MapConfig fields: the track's
        over the defaults), for participants whose agents are built for one crop."""
        return asdict(env_config_from_dict(self.env_config(self.phases[0])).maps)

    @property
    def allowed_sensors(self) -> tuple[str, ...]:
        return self.sensors or TRACK_KINDS[self.kind]

    def phase(self, name: str) -> Phase | None:
        return next((p for p in self.phases if p.name == name), None)

    def env_config(
        self,
        phase: Phase,
        sensors: tuple[str, ...] | None = None,
        maps: Mapping[str, Any] | None = None,
    ) -> dict[str, Any]:
        """The environment config of a run (EnvConfig as nested dicts, no episodes yet)."""
        return {
            "task": {
                "num_goals": self.num_goals,
                "max_steps": phase.max_steps or self.max_steps,
                **self.rules,
            },
            "camera": dict(self.camera),
            "maps": {**self.maps, **(maps or {})},
            "sensors": list(sensors if sensors is not None else self.allowed_sensors),
        }


@dataclass(frozen=True)
class Challenge:
    """The whole challenge: its name, the secret, time limits, hidden scenes and tracks."""

    name: str
    secret: str
    tracks: tuple[Track, ...]
    limits: Limits = field(default_factory=Limits)
    hidden: HiddenScenes = field(default_factory=HiddenScenes)

    def __post_init__(self) -> None:
        if len(self.secret) < MIN_SECRET_CHARS:
            raise ChallengeError(
                f"challenge secret must have at least {MIN_SECRET_CHARS} characters "
                "(e.g. `python -c 'import secrets; print(secrets.token_urlsafe(32))'`)"
            )
        names = [t.name for t in self.tracks]
        if not names:
            raise ChallengeError("a challenge needs at least one [[tracks]]")
        if len(set(names)) != len(names):
            raise ChallengeError(f"track names repeat: {names}")

    def track(self, name: str) -> Track | None:
        return next((t for t in self.tracks if t.name == name), None)

    def warnings(self, now: dt.datetime) -> list[str]:
        """What is allowed but likely a mistake: a sealed phase whose date has passed shows
        its results to everyone (a wrong year unseals it)."""
        return [
            f"phase {t.name}/{p.name}: sealed_until {p.sealed_until.isoformat()} is in the past, "
            "so its results are shown to everyone now (a wrong year?)"
            for t in self.tracks
            for p in t.phases
            if p.sealed_until is not None and p.sealed_until <= now
        ]

    def describe(self) -> dict[str, Any]:
        """The public description (no secret): what ``GET /v1/challenge`` answers."""
        return {
            "name": self.name,
            "limits": {
                "step_timeout_s": self.limits.step_timeout_s,
                "max_consecutive_timeouts": self.limits.max_consecutive_timeouts,
                "run_timeout_s": self.limits.run_timeout_s,
                "max_envs_per_run": self.limits.max_envs_per_run,
            },
            "tracks": [
                {
                    "name": t.name,
                    "num_goals": t.num_goals,
                    "kind": t.kind,
                    "sensors": list(t.allowed_sensors),
                    "camera": dict(t.camera),
                    "maps": t.map_config,
                    "metric": t.metric,
                    "max_steps": t.max_steps,
                    **t.rules,
                    "phases": [
                        {
                            "name": p.name,
                            "episodes": p.episodes,
                            "feedback": p.feedback,
                            "episodes_per_run": p.episode_set,
                            "daily_quota": p.daily_quota,
                            "total_quota": p.total_quota,
                            "sealed_until": None
                            if p.sealed_until is None
                            else p.sealed_until.isoformat(),
                        }
                        for p in t.phases
                    ],
                }
                for t in self.tracks
            ],
        }


def _check_range(where: str, value: float, low: float, high: float, low_open: bool = False) -> None:
    ok = (low < value if low_open else low <= value) and value <= high
    if not ok:
        bracket = "(" if low_open else "["
        raise ChallengeError(f"{where} must be in {bracket}{low}, {high}], got {value!r}")


def _check_name(where: str, name: str) -> None:
    if not _NAME.fullmatch(name):
        raise ChallengeError(
            f"{where} must be 1–40 lowercase letters, digits, '.', '_' or '-', got {name!r}"
        )
