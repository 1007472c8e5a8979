"""A shared-memory buffer per simulator worker that carries its replies' parts (the encoded
observations) to the server process without the pipe.

Through the pipe a 256² RGB-D step (~460 kB) was copied four times in the server process
(socket read, ``BytesIO``, ``getvalue``, the response body); from this buffer it is copied
once, as it is read. The worker writes a reply's parts back to back and sends their lengths in
the reply's header; the server copies them out as soon as the header arrives, before it can
send the worker anything else, so a worker never overwrites parts that were not yet read.

The server process creates the segment (Python's resource tracker unlinks it if the server
dies) and the worker maps it by name, outside ``SharedMemory`` so that the worker's exit never
unlinks it. A reply too large for the buffer, or a machine whose ``/dev/shm`` cannot hold it
(Docker's default is 64 MB), goes through the pipe as before.
"""

from __future__ import annotations

import logging
import mmap
import os
from collections.abc import Sequence
from multiprocessing.shared_memory import SharedMemory

log = logging.getLogger("multion.api")

REPLY_BUFFER_BYTES = 16 * 2**20
"""Per worker: 34 steps of one 256² RGB-D env, or one step of 16 such envs at once."""


class ReplyBuffer:
    """One mapped segment; ``owner`` (the server's side) unlinks it when closed."""

    def __init__(self, name: str, size: int, view: memoryview, owner: SharedMemory | None):
        self.name, self.size = name, size
        self._view = view
        self._owner = owner
        self._map: mmap.mmap | None = None

    @classmethod
    def create(cls, size: int | None = None) -> ReplyBuffer | None:
        """A new segment with all its memory reserved now, or None (logged) where shared
        memory cannot hold it: then the pipe carries every reply. ``size``: default
        :data:`REPLY_BUFFER_BYTES`."""
        size = REPLY_BUFFER_BYTES if size is None else size
        try:
            segment = SharedMemory(create=True, size=size)
        except OSError as error:
            log.warning("no shared memory for a worker's replies (%s): using its pipe", error)
            return None
        try:
            # Reserve the pages: a full /dev/shm would otherwise kill a process with SIGBUS
            # at its first write, instead of failing here.
            fd = os.open(_path(segment.name), os.O_RDWR)
            try:
                os.posix_fallocate(fd, 0, size)
            finally:
                os.close(fd)
        except OSError as error:
            segment.close()
            segment.unlink()
            log.warning(
                "shared memory cannot hold %d MiB for a worker's replies (%s): using its pipe",
                size // 2**20,
                error,
            )
            return None
        assert segment.buf is not None
        return cls(segment.name, size, segment.buf, segment)

    @classmethod
    def attach(cls, name: str, size: int) -> ReplyBuffer:
        """The worker's side: map the server's segment."""
        fd = os.open(_path(name), os.O_RDWR)
        try:
            mapped = mmap.mmap(fd, size)
        finally:
            os.close(fd)
        buffer = cls(name, size, memoryview(mapped), None)
        buffer._map = mapped
        return buffer

    def write(self, parts: Sequence[bytes]) -> list[int] | None:
        """Put ``parts`` back to back; their lengths, or None if they do not fit."""
        lengths = [len(part) for part in parts]
        if sum(lengths) > self.size:
            return None
        offset = 0
        for part, length in zip(parts, lengths, strict=True):
            self._view[offset : offset + length] = part
            offset += length
        return lengths

    def read(self, lengths: Sequence[int]) -> list[bytes]:
        """Copies of the parts last written (lengths from the reply's header)."""
        if any(length < 0 for length in lengths) or sum(lengths) > self.size:
            raise ValueError(f"reply parts of {list(lengths)} bytes do not fit the buffer")
        parts, offset = [], 0
        for length in lengths:
            parts.append(bytes(self._view[offset : offset + length]))
            offset += length
        return parts

    def close(self) -> None:
        """Unmap; the owner also removes the segment."""
        self._view.release()
        if self._map is not None:
            self._map.close()
        if self._owner is not None:
            self._owner.close()
            self._owner.unlink()
            self._owner = None


def _path(name: str) -> str:
    return f"/dev/shm/{name.lstrip('/')}"
