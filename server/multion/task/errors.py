"""The errors the task raises for input it refuses: the caller's mistake, never a bug.

Each is a :class:`~multion.config.errors.UsageError` and a subclass of the wire error the API
answers with (``multion_client.errors``): the server's worker (``api/worker_process.py``)
catches the wire errors' base class and sends the error's own ``code`` and ``status``; any other
exception raised by the env is a bug and becomes a logged 500. The wire errors keep the builtin
the env raised before (``InvalidAction`` is a ``ValueError``, ``EpisodeOver`` a
``RuntimeError``), so code that catches those keeps working.
"""

from __future__ import annotations

from multion.config.datasets import DatasetError
from multion.config.errors import UsageError
from multion_client.errors import BadRequest, EpisodeOver, InvalidAction, InvalidEpisode


class TaskError(UsageError):
    """Input the task cannot use; the message says what and why (safe to show to a client)."""


class BadResetOptionError(TaskError, BadRequest, ValueError):
    """A ``reset`` seed or option of the wrong name, type or range (400 ``bad_request``)."""


class EpisodeNotFoundError(TaskError, InvalidEpisode, ValueError):
    """``reset`` asked for an ``episode_index`` or ``episode_id`` the dataset does not hold
    (422 ``invalid_episode``)."""


class BadEpisodeError(TaskError, InvalidEpisode, DatasetError):
    """An episode (inline, or from a dataset) that cannot be played: malformed, an unknown
    scene, a start that is not navigable, an unreachable goal (422 ``invalid_episode``)."""


class IllegalActionError(TaskError, InvalidAction):
    """``step`` got something that is not one of the task's actions (400 ``invalid_action``)."""


class EpisodeOverError(TaskError, EpisodeOver):
    """``step`` was called after the episode ended; call ``reset`` (409 ``episode_over``)."""
