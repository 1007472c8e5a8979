"""Hidden houses are the calibrated benchmark: `random-oracle-found` on 200 fresh hidden 1-ON
episodes (what a test phase's run plays) within ±5 points of its figure on the packaged val
episodes, as `docs/baselines.md` reports it (1,000 episodes, `scripts/calibrate_houses.py`)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from multion.config.datasets import save_dataset
from multion.leaderboard.challenge import Challenge, Phase, Track
from multion.leaderboard.challenge_file import load_challenge, write_challenge
from multion.leaderboard.hidden import HiddenEpisodes, RunDraw
from multion.scenes.registry import layout_for
from multion_agents.evaluate import EvalSettings, evaluate

ROOT = Path(__file__).resolve().parents[2]
EPISODES = 200
TOLERANCE = 5.0

CHALLENGE = Challenge(
    name="calibration",
    secret="calibration-secret-0123456789",
    tracks=(
        Track("1-on", num_goals=1, phases=(
            Phase("test-standard", episodes=EPISODES, houses=11, feedback="aggregate"),
        )),
    ),
)  # fmt: skip


def documented_val_success() -> float:
    """`random-oracle-found`'s 1-ON Success on the val split, from docs/baselines.md."""
    text = (ROOT / "docs" / "baselines.md").read_text()
    row = re.search(r"^\| random-oracle-found \| 1-ON \| (\d+) \| ([\d.]+) ", text, re.M)
    assert row is not None, "docs/baselines.md has no random-oracle-found 1-ON row"
    assert int(row.group(1)) >= 1000
    return float(row.group(2))


@pytest.mark.slow
def test_hidden_houses_play_like_the_packaged_val_houses(tmp_path: Path) -> None:
    challenge = load_challenge(write_challenge(CHALLENGE, tmp_path / "challenge.toml"))
    track = challenge.tracks[0]
    phase = track.phases[0]
    assert phase.episode_set == "fresh"
    hidden = HiddenEpisodes(challenge, in_subprocess=False)
    for house in hidden.houses[(track.name, phase.name)]:  # the generator's own 8-16 rooms
        assert 8 <= int(layout_for(house).metadata["room_count"]) <= 16
    draw = RunDraw("calibration-run", "fresh", tuple(range(EPISODES)))
    episodes = [hidden.episode(track, phase, draw, p) for p in range(EPISODES)]
    dataset = save_dataset(tmp_path / "hidden.json.gz", episodes, 1, "val", {"hidden": True})
    settings = EvalSettings(
        agent="random-oracle-found", num_goals=1, split="val", seed=0, in_process=True,
        workers=2, dataset=str(dataset),
    )  # fmt: skip
    result = evaluate(settings, progress=False)
    assert len(result.records) == EPISODES
    success = 100 * float(np.mean([r.metrics["success"] for r in result.records]))
    val = documented_val_success()
    print(f"random-oracle-found 1-ON Success: hidden {success:.1f} %, val {val:.1f} %")
    assert abs(success - val) <= TOLERANCE, f"hidden {success:.1f} % vs val {val:.1f} %"
