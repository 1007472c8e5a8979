"""The challenge file: a valid one reads, every mistake is named with its field and range, and
the hidden houses and episodes come from the secret alone."""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import pytest

from multion.config.scenes import SPLIT_SIZES
from multion.config.task import MapConfig
from multion.leaderboard.challenge import (
    Challenge,
    ChallengeError,
    HiddenScenes,
    Limits,
    Phase,
    Track,
)
from multion.leaderboard.challenge_file import challenge_toml, load_challenge, write_challenge
from multion.leaderboard.hidden import (
    HIDDEN_HOUSE_BASE,
    generate_hidden_episodes,
    hidden_houses,
    run_order,
)
from multion.scenes.registry import layout_for, scene_split


def test_the_tiny_challenge_reads(challenge_file: Path) -> None:
    challenge = load_challenge(challenge_file)
    assert [t.name for t in challenge.tracks] == ["1-on", "1-on-oracle"]
    standard, oracle = challenge.tracks
    assert "oracle_map" not in standard.allowed_sensors and "oracle_map" in oracle.allowed_sensors
    assert standard.phase("minival").feedback == "episodes"
    assert oracle.phase("test-challenge").sealed_until.year == 2999
    assert "secret" not in str(challenge.describe())
    assert standard.metric == "ppl"  # the MultiON challenge's ranking metric by default


def test_the_description_names_each_tracks_oracle_maps(challenge_file: Path) -> None:
    """GET /v1/challenge says which oracle crop a run gets: the defaults (the reference's 50
    cells of 0.8 m, goals as 3 x 3 cells) unless the track sets its own."""
    challenge = load_challenge(challenge_file)
    described = {t["name"]: t for t in challenge.describe()["tracks"]}
    assert described["1-on-oracle"]["maps"] == asdict(MapConfig())
    assert (MapConfig().ego_size, MapConfig().goal_cells) == (50, 3)
    track = dataclasses.replace(challenge.tracks[1], maps={"ego_size": 21, "goal_cells": 1})
    smaller = dataclasses.replace(challenge, tracks=(track,)).describe()["tracks"][0]["maps"]
    assert smaller == {**asdict(MapConfig()), "ego_size": 21, "goal_cells": 1}


def test_a_written_challenge_reads_back_equal(tmp_path: Path) -> None:
    """challenge_file writes what load_challenge reads: every field that differs from its
    default (and only those), of every type a challenge file holds."""
    every = Challenge(
        name="all-fields",
        secret='a "quoted" secret \\ 0123456789',
        limits=Limits(step_timeout_s=2.5, max_consecutive_timeouts=4, run_timeout_s=600,
                      max_envs_per_run=2),
        hidden=HiddenScenes(rooms=(2, 3)),
        tracks=(
            Track("2-on", num_goals=2, kind="oracle", sensors=("rgb", "oracle_map"),
                  camera={"width": 24, "height": 16, "hfov_deg": 90.0}, maps={"ego_size": 21},
                  max_steps=30, metric="success", phases=(
                Phase("minival", episodes=3, houses=1, feedback="episodes", daily_quota=4,
                      max_steps=20),
                Phase("sealed", episodes=2, feedback="sealed", total_quota=1,
                      sealed_until=dt.datetime(2999, 1, 2, 3, 4, 5, tzinfo=dt.timezone.utc),
                      episodes_per_run="fixed"),
            )),
        ),
    )  # fmt: skip
    path = write_challenge(every, tmp_path / "every.toml")
    assert load_challenge(path) == every
    assert "run_timeout_s = 600" in path.read_text()
    plain = Challenge(
        "plain", "plain-secret-0123456789", (Track("1-on", 1, phases=(Phase("p", 1),)),)
    )
    text = challenge_toml(plain)
    assert "[limits]" not in text and "[hidden]" not in text and "kind" not in text
    assert load_challenge(write_challenge(plain, tmp_path / "plain.toml")) == plain


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('name = "tiny"', 'name = "tiny"\ncolour = 1', r"unknown field\(s\) \['colour'\]"),
        (
            "max_consecutive_timeouts = 2",
            "max_consecutive_timeouts = 0",
            r"max_consecutive_timeouts must be in \[1, 1000\], got 0",
        ),
        ("rooms = [1, 1]", "rooms = [3, 17]", r"hidden.rooms\[1\] must be in \[3, 16\]"),
        (
            "num_goals = 1\ncamera",
            'num_goals = 1\nkind = "cheating"\ncamera',
            "kind must be one of",
        ),
        ("episodes = 3", "episodes = 0", r"episodes must be in \[1, 100000\], got 0"),
        ("total_quota = 1", 'total_quota = 1\nfeedback = "sealed"', "needs sealed_until"),
        (
            "camera = { width = 32, height = 32 }",
            "camera = { widht = 32 }",
            "unknown field 'camera.widht'",
        ),
        (
            'num_goals = 1\nkind = "oracle"',
            'num_goals = 1\nkind = "oracle"\nsensors = ["x-ray"]',
            r"unknown sensor\(s\) \['x-ray'\]",
        ),
        ("episodes = 3", 'episodes = "3"', "episodes must be int"),
        ('secret = "test-secret-0123456789abcdef"', 'secret = "short"', "at least 16 characters"),
    ],
)
def test_mistakes_are_named(
    challenge_file: Path, tmp_path: Path, old: str, new: str, message: str
) -> None:
    text = challenge_file.read_text()
    assert old in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new, 1))
    with pytest.raises(ChallengeError, match=message):
        load_challenge(bad)


def test_the_secret_may_come_from_the_environment(challenge_file: Path, tmp_path: Path) -> None:
    text = challenge_file.read_text().replace(
        'secret = "test-secret-0123456789abcdef"', 'secret_env = "LB_SECRET"'
    )
    path = tmp_path / "env.toml"
    path.write_text(text)
    with pytest.raises(ChallengeError, match="LB_SECRET"):
        load_challenge(path, environ={})
    assert load_challenge(path, environ={"LB_SECRET": "x" * 20}).secret == "x" * 20
    with pytest.raises(ChallengeError, match="not a readable TOML"):
        (tmp_path / "broken.toml").write_text("[challenge\n")
        load_challenge(tmp_path / "broken.toml")


def test_hidden_houses_and_episodes_come_from_the_secret(
    challenge_file: Path, tmp_path: Path, make_challenge: Callable[..., Path]
) -> None:
    challenge = load_challenge(challenge_file)
    track = challenge.tracks[0]
    phase = track.phase("minival")
    houses = hidden_houses(challenge, track, phase)
    assert len(houses) == phase.houses
    for house in houses:
        number = int(house.split("-")[1])
        assert number >= HIDDEN_HOUSE_BASE > sum(SPLIT_SIZES.values())  # never a packaged house
        assert scene_split(house) is None
        assert len(layout_for(house).rooms) == 1  # hidden.rooms = [1, 1]
    first = generate_hidden_episodes(challenge, track, phase)
    assert first == generate_hidden_episodes(challenge, track, phase)  # same secret, same episodes
    assert {e.scene_id for e in first} <= set(houses)
    other = load_challenge(challenge_file, environ={})
    object.__setattr__(other, "secret", "another-secret-0123456789")
    assert hidden_houses(other, track, phase) != houses
    assert sorted(run_order(challenge, "a", 10)) == list(range(10))
    assert run_order(challenge, "a", 10) != run_order(challenge, "b", 10)
