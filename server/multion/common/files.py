"""Atomic file writes: a reader never sees half a file, a failure leaves the old file as it was.

Every file the project writes for others to read (datasets, caches of meshes and grids,
results, checkpoints, exports) goes through :func:`replacing`: the writer fills a temporary
file beside the target, which is synced to disk and then replaces the target in one rename (so
a crash, even of the machine, leaves the old file or the new one). Two processes filling
the same cache write different temporary files, and the last rename wins whole.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def replacing(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix, for writers that read it); it replaces
    ``path`` if the block succeeds and is removed if it fails."""
    handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(handle)
    temporary = Path(name)
    try:
        yield temporary
        os.chmod(temporary, 0o644)  # mkstemp makes owner-only files; these are for sharing
        with temporary.open("rb") as written:  # on disk before the rename makes it the file
            os.fsync(written.fileno())
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def write_atomically(path: Path, data: str | bytes) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` through a temporary file."""
    with replacing(path) as temporary:
        if isinstance(data, bytes):
            temporary.write_bytes(data)
        else:
            temporary.write_text(data, encoding="utf-8", newline="")
