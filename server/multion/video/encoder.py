"""MP4 files that browsers play: H.264 (libx264 from PyAV's wheels), yuv420p, moov atom first.

The size is bounded by x264's rate control: quality-based (CRF) but never above
``MAX_BITRATE`` over any ``VBV_BUFFER`` window, so a video of ``s`` seconds is at most
``(MAX_BITRATE * s + VBV_BUFFER) / 8`` bytes plus the container's few kB (:func:`size_bound`).
"""

from __future__ import annotations

from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from multion.config.errors import UsageError

FPS = 10
"""Frames per second: one step every 0.1 s (the environment's ``render_fps``)."""
MAX_BITRATE = 500_000
"""Bits per second at most (x264 ``maxrate``); typical episodes use about 200 kbit/s."""
VBV_BUFFER = 1_000_000
"""Bits (x264 ``bufsize``): how far above the rate a short stretch may go."""
CONTAINER_BYTES = 64_000
"""A generous allowance for the MP4 boxes (sample tables: a few bytes a frame)."""
SETUP_VIDEO = "install the video extra: pip install -e '.[video]' (PyAV)"


class EncoderUnavailable(UsageError, RuntimeError):
    """PyAV (or its H.264 encoder) is not installed; the message says how to install it."""


def _av() -> Any:
    try:
        import av
    except ImportError:
        raise EncoderUnavailable(f"videos need PyAV: {SETUP_VIDEO}") from None
    return av


def check_encoder() -> None:
    """An EncoderUnavailable now rather than after an evaluation, when videos cannot be made."""
    av = _av()
    try:
        av.codec.Codec("libx264", "w")
    except ValueError as error:  # PyAV's UnknownCodecError
        raise EncoderUnavailable(
            f"this PyAV has no libx264 encoder ({error}): {SETUP_VIDEO}"
        ) from None


def size_bound(frames: int, fps: int = FPS) -> int:
    """The most bytes a video of ``frames`` frames can take."""
    return (MAX_BITRATE * frames // fps + VBV_BUFFER) // 8 + CONTAINER_BYTES


class Mp4Writer:
    """Writes (height, width, 3) uint8 RGB frames, all of one even size, to an MP4 file."""

    def __init__(self, path: Path, width: int, height: int, fps: int = FPS) -> None:
        if width % 2 or height % 2:
            raise ValueError(f"frame size must be even for yuv420p, got {width}x{height}")
        av = _av()
        self._av = av
        self.size = (width, height)
        self.frames = 0
        self._container = av.open(
            str(path), mode="w", format="mp4", options={"movflags": "+faststart"}
        )
        stream = self._container.add_stream("libx264", rate=fps)
        stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
        stream.options = {
            "crf": "23",
            "preset": "veryfast",
            "maxrate": str(MAX_BITRATE),
            "bufsize": str(VBV_BUFFER),
            # the same frames give the same file: one thread, no time-dependent choices
            "threads": "1",
        }
        self._stream = stream

    def write(self, frame: np.ndarray) -> None:
        if frame.shape != (self.size[1], self.size[0], 3) or frame.dtype != np.uint8:
            raise ValueError(
                f"frame must be {self.size[1]}x{self.size[0]}x3 uint8, got {frame.shape} {frame.dtype}"
            )
        video_frame = self._av.VideoFrame.from_ndarray(frame, format="rgb24")
        for packet in self._stream.encode(video_frame):
            self._container.mux(packet)
        self.frames += 1

    def close(self) -> None:
        for packet in self._stream.encode():  # flush the encoder's delayed frames
            self._container.mux(packet)
        self._container.close()

    def __enter__(self) -> Mp4Writer:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        if error is None:
            self.close()
        else:
            self._container.close()


def read_frames(path: Path) -> list[np.ndarray]:
    """The decoded RGB frames of a video (for checks and tests)."""
    av = _av()
    with av.open(str(path)) as container:
        return [frame.to_ndarray(format="rgb24") for frame in container.decode(video=0)]
