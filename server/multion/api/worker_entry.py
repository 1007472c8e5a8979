"""Where a simulator worker process starts: the only function the server hands to ``spawn``.

The spawn context pickles a process's target by its module and name, so the server process
imports this small module and never the simulator: :mod:`multion.api.worker_process` (and with
it PyBullet, the env and the renderers) is imported in the child, inside :func:`run_worker`.
"""

from __future__ import annotations

from multiprocessing.connection import Connection


def run_worker(
    conn: Connection, memory_limit_bytes: int, reply_buffer: tuple[str, int] | None = None
) -> None:
    """Import the simulator in this (child) process and serve the server's commands;
    ``reply_buffer``: the name and size of the shared memory its replies' parts go through."""
    from multion.api.worker_process import worker_main  # the child's import, never the server's

    worker_main(conn, memory_limit_bytes, reply_buffer)
