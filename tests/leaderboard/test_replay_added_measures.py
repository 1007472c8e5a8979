"""A replay compares the metrics a run stored: a measure added to the task after the run was
stored (``cells_visited``) is no difference, a stored one that changed is."""

from __future__ import annotations

from multion.leaderboard.replay import ReplayedEpisode
from multion.leaderboard.results import missed_metrics
from multion.task.measures import metrics_as_stored


def test_a_measure_the_stored_run_lacks_is_no_difference() -> None:
    stored = {"success": 1.0, "steps": 40, "end_reason": "success"}
    replayed = {**stored, "cells_visited": 3}
    assert ReplayedEpisode(0, stored, replayed, 40).same
    assert not ReplayedEpisode(0, stored, {**replayed, "steps": 41}, 40).same
    assert not ReplayedEpisode(0, {**stored, "cells_visited": 2}, replayed, 40).same
    # a stored measure the replay no longer gives is a difference
    assert not ReplayedEpisode(0, {**stored, "gone": 1}, replayed, 40).same


def test_an_older_placeholder_still_reads_as_one() -> None:
    placeholder = missed_metrics(1, "abandoned")
    older = {key: value for key, value in placeholder.items() if key != "cells_visited"}
    assert metrics_as_stored(placeholder, older) == older
    assert metrics_as_stored(placeholder, {**older, "steps": 3}) != {**older, "steps": 3}
