"""The errors the task raises for input it refuses: the caller's mistake, never a bug.

The server's worker (``api/worker_process.py``) catches these by name and answers with the
matching 4xx; any other exception raised by the env is a bug and becomes a logged 500. Each is
also a subclass of the builtin the env raised before (``ValueError``, ``RuntimeError``), so code
that catches those keeps working.
"""

from __future__ import annotations

from multion.config.datasets import DatasetError


class TaskError(Exception):
    """Input the task cannot use; the message says what and why (safe to show to a client)."""


class BadResetOptionError(TaskError, ValueError):
    """A ``reset`` seed or option of the wrong name, type or range."""


class EpisodeNotFoundError(TaskError, ValueError):
    """``reset`` asked for an ``episode_index`` or ``episode_id`` the dataset does not hold."""


class BadEpisodeError(DatasetError, TaskError):
    """An episode (inline, or from a dataset) that cannot be played: malformed, an unknown
    scene, a start that is not navigable, an unreachable goal."""


class IllegalActionError(TaskError, ValueError):
    """``step`` got something that is not one of the task's actions."""


class EpisodeOverError(TaskError, RuntimeError):
    """``step`` was called after the episode ended; call ``reset``."""
