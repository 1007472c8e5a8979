"""The participants' guide page: the participant's parts of ``docs/leaderboard.md``, rendered.

The file is written for organisers too (serving, admin commands, tests); a participant needs
the introduction, "For participants" and "The protocol". They are rendered with markdown-it-py
(CommonMark, tables on, raw HTML off, so the page's Content-Security-Policy stays simple).
The examples are written for a made-up server (``https://challenge.example.org``, track
``3-on``): the served page names the serving challenge's own host, track and phases instead.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass

from markdown_it import MarkdownIt

from multion.leaderboard.challenge import Challenge

PARTICIPANT_SECTIONS = ("For participants", "The protocol")
"""The ``##`` sections of the guide shown on the page, in the file's order."""
_SECTION = re.compile(r"^## (.+)$", re.MULTILINE)
EXAMPLE_URL = "https://challenge.example.org"
"""The made-up server of the guide's examples."""
_SERVER_URL = re.compile(r"https?://[A-Za-z0-9.-]+(:[0-9]{1,5})?")
"""What a served URL may look like to replace it (the Host header is the client's to set)."""
_NAME = r"[a-z0-9][a-z0-9._-]*"


@dataclass(frozen=True)
class ServedExamples:
    """What the served guide's examples name: this server and one of its tracks."""

    url: str
    track: str
    phase: str
    """The track's first phase (the guide's ``minival``)."""
    test_phase: str
    """Its first phase without per-episode feedback (the guide's ``test-standard``), else
    ``phase``."""


def served_examples(challenge: Challenge, url: str) -> ServedExamples:
    """Examples on ``url`` with the challenge's first track (the made-up host if ``url`` is
    not a plain http(s) host)."""
    track = challenge.tracks[0]
    first = track.phases[0].name
    test = next((p.name for p in track.phases if p.feedback != "episodes"), first)
    plain = url.rstrip("/")
    return ServedExamples(plain if _SERVER_URL.fullmatch(plain) else EXAMPLE_URL, track.name,
                          first, test)  # fmt: skip


def localise(text: str, served: ServedExamples) -> str:
    """The guide's examples with the served host, track and phases: the command-line options,
    ``RunEnv`` arguments and ``MULTION_*`` variables of its code (prose naming the
    reference's tracks and phases is left as written)."""
    replacements = [
        (re.escape(EXAMPLE_URL), served.url),
        (rf"--track {_NAME}", f"--track {served.track}"),
        (rf'track="{_NAME}"', f'track="{served.track}"'),
        (rf"MULTION_TRACK={_NAME}", f"MULTION_TRACK={served.track}"),
        (rf"--phase test-{_NAME}", f"--phase {served.test_phase}"),
        (r"--phase minival\b", f"--phase {served.phase}"),
        (r'phase="minival"', f'phase="{served.phase}"'),
        (r"MULTION_PHASE=minival\b", f"MULTION_PHASE={served.phase}"),
    ]
    for pattern, replacement in replacements:  # names and URL hold no backslash: literal
        text = re.sub(pattern, replacement, text)
    return text


def participant_markdown(text: str) -> str:
    """The guide's introduction (its tables too: who does what, and the known problems of
    other graders and what this one does about them) and its participant sections."""
    starts = [(m.start(), m.group(1).strip()) for m in _SECTION.finditer(text)]
    intro = text[: starts[0][0]] if starts else text
    intro = re.sub(r"^# .*\n", "", intro, count=1)  # the page has its own h1
    kept = [intro.strip()]
    for k, (start, title) in enumerate(starts):
        end = starts[k + 1][0] if k + 1 < len(starts) else len(text)
        if title in PARTICIPANT_SECTIONS:
            kept.append(text[start:end].strip())
    return "\n\n".join(kept) + "\n"


def _scrolling(html: str, tag: str, label: str) -> str:
    """Wrap every ``<tag>`` block in a focusable, named region that scrolls sideways (the
    pages' own tables do the same): code and tables are wider than a phone."""
    count = itertools.count(1)

    def region(_: re.Match[str]) -> str:  # numbered: a page's regions need distinct names
        return (
            f'<div class="scroll" role="region" tabindex="0" aria-label="{label} {next(count)} '
            f'(scrolls sideways when wider than the screen)"><{tag}>'
        )

    return re.sub(f"<{tag}>", region, html).replace(f"</{tag}>", f"</{tag}></div>")


def render_guide(text: str, served: ServedExamples | None = None) -> str:
    """HTML of the participant parts of the guide (raw HTML in the Markdown is escaped, so the
    only ``<pre>`` and ``<table>`` tags are the renderer's), its examples on ``served``'s
    server and track if given."""
    md = MarkdownIt("commonmark", {"html": False, "linkify": False}).enable("table")
    markdown = participant_markdown(text)
    if served is not None:
        markdown = localise(markdown, served)
    html = md.render(markdown)
    return _scrolling(_scrolling(html, "pre", "Example"), "table", "Table")
