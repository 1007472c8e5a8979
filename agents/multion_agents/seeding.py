"""How an evaluation seeds each episode's agent, and the schemes its runs record.

``multion eval`` re-seeds the agent's random stream before every episode, so results do not
depend on the number of workers or the order episodes are played in. Since issue 53 the seed
comes from the run's seed and the episode's id (:data:`SEED_SCHEME`, ``"episode_id"``): an
episode draws the same in every run that holds it, so re-running one failing episode alone
(``--episodes`` or a one-episode dataset) replays what the full run did. Runs written before
then seeded from the episode's position in the evaluated list (``"index"``): the same episode
drew differently in a 10-episode run than in a 50-episode one. ``metrics.json`` records the
scheme as ``run.seed_scheme``; a run without the field is an ``"index"`` run.

This module imports nothing heavy: :mod:`multion_agents.report` reads runs with it.
"""

from __future__ import annotations

import hashlib

import numpy as np

INDEX = "index"
"""Seeded from ``(seed, position in the evaluated list)``: every run before issue 53, and still
the lanes of ``multion submit`` (a phase's episodes come in one fixed order) and training's
periodic val evaluation (a fixed list)."""
EPISODE_ID = "episode_id"
"""Seeded from ``(seed, episode id)``: ``multion eval`` since issue 53."""
SEED_SCHEMES = (INDEX, EPISODE_ID)
SEED_SCHEME = EPISODE_ID
"""The scheme ``multion eval`` uses and records in ``metrics.json`` (``run.seed_scheme``)."""
OLD_SEED_SCHEME = INDEX
"""The scheme of a run whose ``metrics.json`` has no ``run.seed_scheme``."""


def episode_seed(seed: int, index: int) -> int:
    """The agent's seed for the episode at ``index`` of a list (the ``"index"`` scheme):
    independent streams for every episode."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def episode_id_seed(seed: int, episode_id: str) -> int:
    """The agent's seed for episode ``episode_id`` (the ``"episode_id"`` scheme): the same in
    every run of ``seed`` that plays the episode, wherever it stands in the list."""
    digest = hashlib.sha256(episode_id.encode("utf-8")).digest()
    words = [int(word) for word in np.frombuffer(digest, dtype="<u4")]
    return int(np.random.SeedSequence([seed, *words]).generate_state(1)[0])


def scheme_seed(scheme: str, seed: int, index: int, episode_id: str) -> int:
    """The seed ``scheme`` gives the episode ``episode_id`` played at ``index`` of a run's list;
    a ValueError names the schemes for another."""
    if scheme == INDEX:
        return episode_seed(seed, index)
    if scheme == EPISODE_ID:
        return episode_id_seed(seed, episode_id)
    raise ValueError(f"unknown seed scheme {scheme!r}; schemes: {', '.join(SEED_SCHEMES)}")
