"""Episodes of the version 2 val datasets that tests replay by id (traps the baselines once fell
into, starts the step-path check now refuses). The packaged datasets were regenerated (version 3)
and their ids now name other episodes; these keep their houses (scene generator 2)."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

from multion.config.episode import Episode

DATA = Path(__file__).parent / "data" / "v2_val_episodes.json"


@cache
def _episodes() -> dict[str, Episode]:
    raw = json.loads(DATA.read_text())["episodes"]
    return {item["episode_id"]: Episode.from_dict(item) for item in raw}


def v2_episode(episode_id: str) -> Episode:
    """The version 2 val episode ``episode_id`` (KeyError naming the known ids otherwise)."""
    episodes = _episodes()
    if episode_id not in episodes:
        raise KeyError(f"{episode_id} is not in {DATA.name}: {sorted(episodes)}")
    return episodes[episode_id]
