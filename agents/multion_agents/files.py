"""Checks on the files and folders a command will write (atomic writes: :mod:`multion.common.files`)."""

from __future__ import annotations

import os
from pathlib import Path


def output_directory_problem(path: Path) -> str | None:
    """Why ``path`` cannot become a directory to write results in, or None if it can.

    Checked before long work starts (an evaluation, a training run), so that a bad ``--out`` is
    refused at once rather than after minutes of work. Nothing is created."""
    existing = path
    while not os.path.lexists(existing):
        if existing.parent == existing:
            break
        existing = existing.parent
    if existing.is_symlink() and not existing.exists():
        return f"{existing} is a symbolic link to {os.readlink(existing)!r}, which does not exist"
    if existing.exists() and not existing.is_dir():
        return f"{existing} exists and is not a directory"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"{existing} is not writable"
    return None
