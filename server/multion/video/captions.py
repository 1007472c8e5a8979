"""WebVTT caption tracks: the text of each frame's caption (step, action, current goal, what
just happened), timed to the video, so that a screen reader or a viewer who cannot read the
small frame text follows the episode too."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Cue:
    start_frame: int
    end_frame: int
    """Exclusive: the first frame the cue no longer covers."""
    lines: tuple[str, ...]


def timestamp(frame: int, fps: int) -> str:
    """WebVTT's hh:mm:ss.ttt of the start of ``frame``."""
    millis = frame * 1000 // fps
    hours, rest = divmod(millis, 3_600_000)
    minutes, rest = divmod(rest, 60_000)
    seconds, millis = divmod(rest, 1000)
    return f"{hours:02d}:{minutes:02d}:{seconds:02d}.{millis:03d}"


def _escape(text: str) -> str:
    # WebVTT cue text is markup: '&' and '<' must be escaped, and "-->" ends a cue's timing
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


class CaptionTrack:
    """Cues collected frame by frame; consecutive frames with the same text share one cue."""

    def __init__(self, fps: int) -> None:
        self.fps = fps
        self.cues: list[Cue] = []

    def add(self, start_frame: int, frames: int, lines: tuple[str, ...]) -> None:
        """``lines`` are shown from ``start_frame`` for ``frames`` frames."""
        shown = tuple(" ".join(line.split()) for line in lines if line.strip())
        last = self.cues[-1] if self.cues else None
        if last is not None and last.lines == shown and last.end_frame == start_frame:
            self.cues[-1] = Cue(last.start_frame, start_frame + frames, shown)
        else:
            self.cues.append(Cue(start_frame, start_frame + frames, shown))

    def text(self) -> str:
        """The WebVTT file."""
        blocks = ["WEBVTT"]
        for number, cue in enumerate(self.cues, start=1):
            if not cue.lines:
                continue
            timing = f"{timestamp(cue.start_frame, self.fps)} --> "
            timing += timestamp(cue.end_frame, self.fps)
            blocks.append("\n".join([str(number), timing, *map(_escape, cue.lines)]))
        return "\n\n".join(blocks) + "\n"
