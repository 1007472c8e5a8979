"""The shared memory that carries a worker's replies (``multion.api.reply_buffer``): what goes in
comes out, what does not fit goes through the pipe, and nothing is left in ``/dev/shm``."""

from __future__ import annotations

import errno
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from multion.api import reply_buffer
from multion.api.app import create_app
from multion.api.reply_buffer import ReplyBuffer
from multion.api.settings import ServerSettings
from multion_client.protocol import CONTENT_TYPE, decode, encode, session_path


def segments() -> set[str]:
    return {name for name in os.listdir("/dev/shm") if name.startswith("psm_")}


def test_the_worker_side_reads_what_the_server_side_mapped() -> None:
    owner = ReplyBuffer.create(4096)
    assert owner is not None
    worker = ReplyBuffer.attach(owner.name, owner.size)
    parts = [b"abc", b"", bytes(range(256)) * 4]
    lengths = worker.write(parts)
    assert lengths == [3, 0, 1024]
    assert owner.read(lengths) == parts
    assert worker.write([b"x" * 4097]) is None  # too large: the pipe carries it
    with pytest.raises(ValueError, match="do not fit"):
        owner.read([4000, 100])
    worker.close()
    assert Path(f"/dev/shm/{owner.name.lstrip('/')}").exists()  # the worker never removes it
    owner.close()
    assert not Path(f"/dev/shm/{owner.name.lstrip('/')}").exists()


def test_a_full_dev_shm_means_no_buffer_and_no_segment_left(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def full(fd: int, offset: int, length: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    before = segments()
    monkeypatch.setattr(reply_buffer.os, "posix_fallocate", full)
    assert ReplyBuffer.create(4096) is None
    assert segments() == before


def play(settings: ServerSettings, config: dict[str, Any]) -> list[Any]:
    """Observations of a reset and 6 steps, through a server built with ``settings``."""
    seen = []
    with TestClient(create_app(settings)) as api:
        headers = {"content-type": CONTENT_TYPE}
        body = {"config": config, "num_envs": 2, "auto_reset": True}
        created = api.post("/v1/sessions", content=encode(body), headers=headers)
        session = decode(created.content)["session_id"]
        reset = {"seeds": [3, 4], "options": [None, None]}
        answer = api.post(session_path(session, "reset"), content=encode(reset), headers=headers)
        seen.append(decode(answer.content)["observations"])
        for action in (1, 2, 1, 3, 1, 1):
            step = encode({"actions": [action, action]})
            answer = api.post(session_path(session, "step"), content=step, headers=headers)
            assert answer.status_code == 200, answer.content
            seen.append(decode(answer.content)["observations"])
        api.delete(session_path(session))
    return seen


@pytest.fixture
def settings() -> Iterator[ServerSettings]:
    before = segments()
    yield ServerSettings(workers=1, idle_timeout_s=600)
    assert segments() == before  # each worker's segment went with it


def test_replies_through_the_buffer_the_pipe_or_both_are_the_same(
    settings: ServerSettings, small_config: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    reads: list[list[int]] = []
    read = ReplyBuffer.read

    def counted(self: ReplyBuffer, lengths: list[int]) -> list[bytes]:
        reads.append(list(lengths))
        return read(self, lengths)

    monkeypatch.setattr(ReplyBuffer, "read", counted)
    buffered = play(settings, small_config)
    assert len(reads) >= 7 and all(sum(lengths) > 5000 for lengths in reads[-7:])
    # 32² RGB-D is ~7 kB an env: a 5 kB buffer is too small for every reply, so all go by pipe
    monkeypatch.setattr(reply_buffer, "REPLY_BUFFER_BYTES", 5000)
    piped = play(settings, small_config)
    monkeypatch.setattr(ReplyBuffer, "create", classmethod(lambda cls, size=None: None))
    unbuffered = play(settings, small_config)
    for replies in (piped, unbuffered):
        for ours, theirs in zip(buffered, replies, strict=True):
            for env_ours, env_theirs in zip(ours, theirs, strict=True):
                assert env_ours.keys() == env_theirs.keys()
                for key in env_ours:
                    np.testing.assert_array_equal(env_ours[key], env_theirs[key])
