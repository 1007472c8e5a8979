"""Where the hidden-episode helper reaches the simulator: the functions the server hands over.

A process pool pickles a function by its module and name, so the leaderboard's server process
imports this small module and never the simulator: :mod:`multion.leaderboard.hidden_sampling`
(and with it PyBullet, houses and grids) is imported inside each function, in the helper.
"""

from __future__ import annotations

from multion.config.episode import Episode


def fixed_episode_set(
    num_goals: int, split: str, count: int, seed: int, houses: list[str], num_distractors: int
) -> list[Episode]:
    """A phase's fixed episode set (see :func:`.hidden_sampling.fixed_episode_set`)."""
    from multion.leaderboard import hidden_sampling  # the helper's import, never the server's

    return hidden_sampling.fixed_episode_set(num_goals, split, count, seed, houses, num_distractors)


def episode_in_house(
    house: str, num_goals: int, num_distractors: int, seed: int, episode_id: str, tries: int
) -> Episode | None:
    """One fresh episode, or None (see :func:`.hidden_sampling.episode_in_house`)."""
    from multion.leaderboard import hidden_sampling

    return hidden_sampling.episode_in_house(
        house, num_goals, num_distractors, seed, episode_id, tries
    )


def build_grids(houses: list[str]) -> int:
    """Build the navigable grids of ``houses`` in this process; returns how many."""
    from multion.leaderboard import hidden_sampling

    return hidden_sampling.build_grids(houses)
