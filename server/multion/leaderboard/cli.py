"""``multion leaderboard``: the organisers' commands.

::

    multion leaderboard init --database sqlite:///results.db
    multion leaderboard check --challenge challenge.toml [--generate]
    multion leaderboard tracks --challenge challenge.toml
    multion leaderboard team add "Team Rocket"          # prints the team's token once
    multion leaderboard team list
    multion leaderboard token add "Team Rocket" | revoke "Team Rocket" [--key KEY] | list
    multion leaderboard runs [--team T] [--track 3-on] [--phase minival]
    multion leaderboard export --out results.csv [--best]   # or results.json (with episodes)
    multion leaderboard replay RUN_ID [--write]          # re-score from the stored actions
    multion leaderboard replay RUN_ID --video DIR [--episode N ...]   # film any run's episodes
    multion leaderboard baselines --server URL           # random, explorer, … as baselines

``--database`` defaults to ``$MULTION_LEADERBOARD_DATABASE`` or ``sqlite:///leaderboard.db``,
``--challenge`` to ``$MULTION_LEADERBOARD_CHALLENGE``. Only ``init`` (and ``multion serve``)
create a database; every other command needs an existing one and says which it looked for.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from multion.common.files import write_atomically
from multion.config.errors import UsageError
from multion.config.ranges import ConfigError
from multion.leaderboard.challenge_file import load_challenge
from multion.leaderboard.hidden import HiddenEpisodes, RunDraw
from multion.leaderboard.house_stats import house_stats, stats_table, val_stats
from multion.leaderboard.models import EpisodeRecord, Run, Team, utcnow
from multion.leaderboard.replay import rescore
from multion.leaderboard.run_rows import counted, replay_counts, run_line, run_rows, shown_rows
from multion.leaderboard.storage import (
    Database,
    add_team,
    add_token,
    check_secret,
    current_revision,
    find_team,
    revoke_tokens,
)
from multion.scenes.registry import layout_for
from multion.sim.house_check import points_outside_rooms
from multion_client.errors import MultiONError

if TYPE_CHECKING:
    from multion.config.episode import Episode
    from multion.leaderboard.challenge import Challenge

DEFAULT_DATABASE = "sqlite:///leaderboard.db"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)

    def command(name: str, text: str, challenge: bool = False, database: bool = True) -> Any:
        p = sub.add_parser(name, help=text, description=text)
        if database:
            p.add_argument(
                "--database",
                default=None,
                help="SQLAlchemy URL or SQLite path (default $MULTION_LEADERBOARD_DATABASE or "
                f"{DEFAULT_DATABASE})",
            )
        if challenge:
            p.add_argument(
                "--challenge",
                type=Path,
                default=os.environ.get("MULTION_LEADERBOARD_CHALLENGE"),
                help="the challenge file (default $MULTION_LEADERBOARD_CHALLENGE)",
            )
        return p

    command("init", "create the database or upgrade it to the newest schema")
    p = command("check", "validate a challenge file", challenge=True, database=False)
    p.add_argument("--generate", action="store_true", help="also generate the hidden episodes")
    command("tracks", "list the tracks and phases of a challenge", challenge=True, database=False)
    p = command("team", "add or list teams")
    p.add_argument("team_action", choices=["add", "list"])
    p.add_argument("name", nargs="?")
    p = command("token", "add, revoke or list a team's tokens")
    p.add_argument("token_action", choices=["add", "revoke", "list"])
    p.add_argument("name", help="team name")
    p.add_argument("--key", default=None, help="revoke only this token (its key, mlb_KEY_…)")
    p = command("runs", "list runs")
    for option in ("team", "track", "phase", "state"):
        p.add_argument(f"--{option}", default=None)
    p = command("export", "write results as CSV or JSON (by --out's suffix)", challenge=True)
    p.add_argument("--out", type=Path, required=True, help="results.csv or results.json")
    p.add_argument(
        "--best",
        action="store_true",
        help="only the runs the leaderboard page shows now: each team's best per track and "
        "phase (each baseline method's for the baselines team), none of a sealed phase before "
        "its date (needs --challenge)",
    )
    p = command("replay", "replay a stored run and compare (or re-score) it", challenge=True)
    p.add_argument("run_id")
    p.add_argument("--write", action="store_true", help="store the replayed metrics")
    p.add_argument(
        "--video", type=Path, default=None, metavar="DIR",
        help="instead, film the run's episodes into DIR (MP4 and WebVTT captions; any phase)",
    )  # fmt: skip
    p.add_argument(
        "--episode", type=int, action="append", default=None, metavar="N",
        help="with --video: episode N as the run page numbers them (1: the first; repeat it); "
        "default: the first 3 played",
    )  # fmt: skip
    p = command("baselines", "play the baseline agents through the run protocol")
    p.add_argument(
        "--server", required=True, help="the challenge server's URL (its tracks are played)"
    )
    p.add_argument("--track", action="append", default=None, help="only these tracks")
    p.add_argument("--phase", action="append", default=None, help="only these phases")
    p.add_argument("--agents", nargs="+", default=None, help="default: every baseline allowed")
    p.add_argument("--quiet", action="store_true")


def run(args: argparse.Namespace, more_actions: Mapping[str, Action] | None = None) -> int:
    """Run ``args.action``: one of this module's, or of ``more_actions`` (``baselines``)."""
    actions = {**_ACTIONS, **(more_actions or {})}
    if args.action not in actions:
        print(
            f"multion leaderboard {args.action}: needs the agents (multion_agents)", file=sys.stderr
        )
        return 2
    try:
        return int(actions[args.action](args) or 0)
    except (UsageError, MultiONError) as error:  # a bad file or option, or a server's refusal
        print(f"multion leaderboard {args.action}: {error}", file=sys.stderr)
        return 2


# ---------------------------------------------------------------------- actions
def _challenge(args: argparse.Namespace) -> Any:
    if args.challenge is None:
        raise ConfigError("give --challenge FILE (or set MULTION_LEADERBOARD_CHALLENGE)")
    return load_challenge(args.challenge)


def _database_url(args: argparse.Namespace) -> tuple[str, str]:
    """The database URL to use and where it came from (for error messages)."""
    if args.database:
        return args.database, "--database"
    if os.environ.get("MULTION_LEADERBOARD_DATABASE"):
        return os.environ["MULTION_LEADERBOARD_DATABASE"], "$MULTION_LEADERBOARD_DATABASE"
    return DEFAULT_DATABASE, "the default; give --database URL or set MULTION_LEADERBOARD_DATABASE"


def existing_database(args: argparse.Namespace) -> Database:
    """The existing database (never created here: a typo must not make an empty one)."""
    url, source = _database_url(args)
    return Database.open_existing(url, hint=f" ({source})")


def _init(args: argparse.Namespace) -> int:
    db = Database.open(_database_url(args)[0])
    print(
        f"{db.engine.url.render_as_string(hide_password=True)}: schema {current_revision(db.engine)}"
    )
    db.close()
    return 0


def _check(args: argparse.Namespace) -> int:
    challenge = _challenge(args)

    phases = sum(len(t.phases) for t in challenge.tracks)
    print(
        f"{args.challenge}: challenge {challenge.name!r}, {counted(len(challenge.tracks), 'track')}, "
        f"{counted(phases, 'phase')}: OK"
    )
    for warning in challenge.warnings(utcnow()):
        print(f"  warning: {warning}")
    if args.generate:
        return _generate(challenge)
    return 0


def _generate(challenge: Challenge) -> int:
    """Build every phase's hidden houses and episodes; their statistics beside val's. Refuses
    (exit status 1) a challenge whose houses or episodes are unsound (issue 33)."""
    hidden = HiddenEpisodes(challenge, in_subprocess=False)
    rows = [("packaged val (calibrated)", val_stats())]
    problems: list[str] = []
    for track in challenge.tracks:
        for phase in track.phases:
            houses = hidden.houses[(track.name, phase.name)]
            if phase.episode_set == "fixed":
                episodes = hidden.phase_set(track, phase)
                what = f"{len(episodes)} episodes (one fixed set)"
            else:  # a probe run's first episodes: each run draws its own
                probe = RunDraw("check", "fresh", tuple(range(phase.episodes)))
                count = min(phase.episodes, 10)
                episodes = [hidden.episode(track, phase, probe, k) for k in range(count)]
                what = f"{count} of a probe run's {phase.episodes} fresh episodes drawn"
            print(f"  {track.name}/{phase.name}: {what} in {counted(len(houses), 'hidden house')}")
            stats = house_stats(houses)
            rows.append((f"{track.name}/{phase.name}", stats))
            problems += list(stats.problems) + _episode_problems(episodes)
    print("\n".join(stats_table(rows)))
    if problems:
        print(f"error: {counted(len(problems), 'problem')} in the hidden houses or episodes:")
        print("\n".join(f"  {p}" for p in problems[:20]))
        return 1
    return 0


def _episode_problems(episodes: list[Episode]) -> list[str]:
    """Starts and goals that are not inside a room (or a doorway)."""
    problems = []
    for e in episodes:
        points = [e.start_position[:2]] + [g.position[:2] for g in e.goals]
        if points_outside_rooms(layout_for(e.scene_id), points).any():
            problems.append(f"{e.scene_id}: episode {e.episode_id} starts or has a goal outside")
    return problems


def _tracks(args: argparse.Namespace) -> int:
    challenge = _challenge(args)
    now = utcnow()
    for track in challenge.tracks:
        print(
            f"{track.name}: {track.num_goals}-ON, {track.kind}, ranked by {track.metric}, sensors {', '.join(track.allowed_sensors)}"
        )
        for p in track.phases:
            quota = ", ".join(
                q for q in (
                    f"{p.daily_quota}/day" if p.daily_quota is not None else "",
                    f"{p.total_quota} total" if p.total_quota is not None else "",
                ) if q
            ) or "no quota"  # fmt: skip
            sealed = f", sealed until {p.sealed_until.isoformat()}" if p.sealed_until else ""
            if p.sealed_until is not None and p.sealed_until <= now:
                sealed += " (passed: results shown to everyone)"
            print(
                f"  {p.name}: {counted(p.episodes, 'episode')} in {counted(p.houses, 'house')}, feedback {p.feedback}, {quota}{sealed}"
            )
    return 0


def _team(args: argparse.Namespace) -> int:
    from sqlalchemy import select

    db = existing_database(args)
    try:
        with db.sessions.begin() as session:
            if args.team_action == "add":
                if not args.name:
                    raise ConfigError("team add needs a NAME")
                team, token = add_team(session, args.name)
                print(f"team {team.name!r} added; its token (shown once, keep it secret):")
                print(token)
            else:
                for team in session.scalars(select(Team).order_by(Team.name)):
                    live = sum(1 for t in team.tokens if t.revoked_at is None)
                    print(f"{team.name}\t{live} live token(s)\tsince {team.created_at:%Y-%m-%d}")
    finally:
        db.close()
    return 0


def _token(args: argparse.Namespace) -> int:
    db = existing_database(args)
    try:
        with db.sessions.begin() as session:
            team = find_team(session, args.name)
            if args.token_action == "add":
                print(add_token(session, team))
            elif args.token_action == "revoke":
                print(f"revoked {revoke_tokens(session, team, args.key)} token(s) of {team.name!r}")
            else:
                for token in team.tokens:
                    state = (
                        "live"
                        if token.revoked_at is None
                        else f"revoked {token.revoked_at:%Y-%m-%d %H:%M}"
                    )
                    print(f"mlb_{token.key}_…\t{state}\tcreated {token.created_at:%Y-%m-%d %H:%M}")
    finally:
        db.close()
    return 0


def _runs(args: argparse.Namespace) -> int:
    db = existing_database(args)
    try:
        with db.sessions() as session:
            _check_filters(session, args)
            rows = run_rows(session, args.team, args.track, args.phase, args.state)
    finally:
        db.close()
    for r in rows:
        print(run_line(r))
    if not rows:
        print("no runs")
    return 0


RUN_STATES = ("running", "finished", "ended", "failed")


def _check_filters(session: Any, args: argparse.Namespace) -> None:
    """A filter that matches nothing the database holds is named with what it does hold (a
    typo must not read as "no runs")."""
    from sqlalchemy import distinct, select

    for option, column in (("team", Team.name), ("track", Run.track), ("phase", Run.phase)):
        given = getattr(args, option)
        if given is None:
            continue
        known = sorted(session.scalars(select(distinct(column))))
        if given not in known:
            listed = ", ".join(known[:20]) + (" …" if len(known) > 20 else "") or "none yet"
            where = "teams" if option == "team" else f"{option}s with runs"
            raise ConfigError(f"--{option} {given!r}: no such {option}; {where}: {listed}")
    if args.state is not None and args.state not in RUN_STATES:
        raise ConfigError(f"--state {args.state!r}: states are {', '.join(RUN_STATES)}")


def _export(args: argparse.Namespace) -> int:
    from sqlalchemy import select

    db = existing_database(args)
    try:
        with db.sessions() as session:
            rows = run_rows(session)
            if args.best:
                rows = shown_rows(session, _challenge(args), rows)
            suffix = args.out.suffix.lower()
            if suffix == ".json":
                for row in rows:
                    records = session.scalars(
                        select(EpisodeRecord)
                        .where(EpisodeRecord.run_id == row["run_id"])
                        .order_by(EpisodeRecord.position)
                    )
                    row["episode_records"] = [
                        {"position": e.position, "episode_id": e.episode_id, "end_reason": e.end_reason,
                         "metrics": e.metrics, "actions": e.actions}
                        for e in records
                    ]  # fmt: skip
                text = json.dumps({"runs": rows}, indent=1)
            elif suffix == ".csv":
                buffer = io.StringIO()
                names = list(rows[0]) if rows else ["run_id"]
                writer = csv.DictWriter(buffer, fieldnames=names)
                writer.writeheader()
                writer.writerows(rows)
                text = buffer.getvalue()
            else:
                raise ConfigError(f"--out must end in .csv or .json, got {args.out}")
    finally:
        db.close()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(args.out, text)
    print(f"wrote {len(rows)} runs to {args.out}")
    return 0


def _replay(args: argparse.Namespace) -> int:
    challenge = _challenge(args)
    if args.video is not None:
        return _film(args, challenge)
    if args.episode is not None:
        raise ConfigError("--episode goes with --video DIR (which episodes to film)")
    db = existing_database(args)
    try:
        with db.sessions.begin() as session:
            check_secret(session, challenge.secret, remember=False)
            report = rescore(session, challenge, args.run_id, write=args.write)
    finally:
        db.close()
    print(f"run {args.run_id}: {replay_counts(report)}")
    if report["differences"]:
        print(f"  {len(report['differences'])} episode(s) differ from the stored record: {report['differences']}"
              + (" (stored records updated)" if args.write else " (use --write to re-score)"))  # fmt: skip
        return 0 if args.write else 1
    print("  identical to the stored records")
    return 0


def _film(args: argparse.Namespace, challenge: Challenge) -> int:
    from multion.leaderboard.cli_film import film

    db = existing_database(args)
    try:
        film(db, challenge, args.run_id, args.episode, args.video)
    finally:
        db.close()
    return 0


_ACTIONS = {
    "init": _init,
    "check": _check,
    "tracks": _tracks,
    "team": _team,
    "token": _token,
    "runs": _runs,
    "export": _export,
    "replay": _replay,
}
"""The actions of this layer; ``baselines`` plays agents, which live above it: the
``multion leaderboard`` command (``multion_agents.cli_leaderboard``) adds it to :func:`run`."""

Action = Callable[[argparse.Namespace], int]
