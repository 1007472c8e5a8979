"""``multion leaderboard check --generate`` builds the hidden houses and episodes, prints their
statistics beside val's and refuses a challenge whose houses or episodes are unsound (issue 33).

val's statistics (eleven 8–16 room houses, about a minute) are stubbed: what is under test is the
hidden houses'."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from multion.leaderboard import house_stats
from multion.leaderboard.challenge import Challenge, HiddenScenes
from multion.leaderboard.challenge_file import write_challenge
from multion.leaderboard.house_stats import HouseStats
from multion_agents.cli import main


@pytest.fixture
def small_houses(challenge: Challenge, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setattr(
        house_stats, "val_stats", lambda: HouseStats(11, (8, 16, 12.0), (150, 400, 250), 0.55)
    )
    monkeypatch.setenv("MULTION_NAVGRID_CACHE", "off")
    # one track, one phase, rooms 1–2: the houses that walked on their roofs
    track = challenge.tracks[0]
    small = dataclasses.replace(
        challenge,
        hidden=HiddenScenes(rooms=(1, 2)),
        tracks=(dataclasses.replace(track, phases=track.phases[:1]),),
    )
    return write_challenge(small, tmp_path / "small.toml")


def test_small_hidden_houses_pass_and_their_navigable_share_is_below_the_footprint(
    small_houses: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["leaderboard", "check", "--challenge", str(small_houses), "--generate"]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("1-on/minival"))
    assert 0 < float(row.split()[-1]) <= 100, row
    assert "error" not in out


def test_unsound_houses_are_refused(
    small_houses: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(
        house_stats, "grid_problems", lambda *a: ["navigable 40 m² exceeds the footprint's 12 m²"]
    )
    assert main(["leaderboard", "check", "--challenge", str(small_houses), "--generate"]) == 1
    out = capsys.readouterr().out
    assert "error: 1 problem in the hidden houses or episodes" in out
    assert "exceeds the footprint" in out


def test_long_track_names_keep_the_columns_in_line(
    small_houses: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from multion.leaderboard.challenge_file import load_challenge

    challenge = load_challenge(small_houses)
    long_name = "5-on-cylinders-with-distractors-2026"
    track = dataclasses.replace(challenge.tracks[0], name=long_name)
    renamed = write_challenge(dataclasses.replace(challenge, tracks=(track,)), small_houses)
    assert main(["leaderboard", "check", "--challenge", str(renamed), "--generate"]) == 0
    out = capsys.readouterr().out
    assert "in 1 hidden house\n" in out  # not "1 hidden houses"
    start = next(k for k, line in enumerate(out.splitlines()) if line.startswith("houses of"))
    table = out.splitlines()[start : start + 3]  # the header, val's row, the track's row
    assert table[2].startswith(f"{long_name}/minival ")
    # every column ends where its title ends: the lines are equally long, numbers right-aligned
    assert len({len(line) for line in table}) == 1, table
    for title in ("count", "rooms", "mean", "nav %"):
        end = table[0].index(title) + len(title)
        assert all(
            line[end - 1] != " " and line[end : end + 1] in ("", " ") for line in table[1:]
        ), (
            title,
            table,
        )


def test_a_range_of_one_value_is_printed_as_the_value() -> None:
    """Issue 53 item 5: one-room houses printed as rooms "1–1" (and a footprint "12 (12–12)")."""
    width = len(house_stats.header())
    one = HouseStats(3, (1, 1, 1.0), (11.9, 12.2, 12.0), 0.5).row("1-on/minival")
    assert one.split()[1:] == ["3", "1", "1.0", "12", "50.0"] and len(one) == width
    assert "–" not in one
    many = HouseStats(11, (8, 16, 12.0), (150, 400, 250), 0.55).row("val")
    assert many.split()[1:] == ["11", "8–16", "12.0", "250", "(150–400)", "55.0"]
    assert len(many) == width
