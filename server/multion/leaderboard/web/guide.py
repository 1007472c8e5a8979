"""The participants' guide page: the participant's parts of ``docs/leaderboard.md``, rendered.

The file is written for organisers too (serving, admin commands, tests); a participant needs
the introduction, "For participants" and "The protocol". They are rendered with markdown-it-py
(CommonMark, tables on, raw HTML off, so the page's Content-Security-Policy stays simple).
"""

from __future__ import annotations

import itertools
import re

from markdown_it import MarkdownIt

PARTICIPANT_SECTIONS = ("For participants", "The protocol")
"""The ``##`` sections of the guide shown on the page, in the file's order."""
_SECTION = re.compile(r"^## (.+)$", re.MULTILINE)


def participant_markdown(text: str) -> str:
    """The guide's introduction (up to its first table) and its participant sections."""
    starts = [(m.start(), m.group(1).strip()) for m in _SECTION.finditer(text)]
    intro = text[: starts[0][0]] if starts else text
    intro = intro.split("\n|", 1)[0]  # the tables after the first paragraph are for organisers
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


def render_guide(text: str) -> str:
    """HTML of the participant parts of the guide (raw HTML in the Markdown is escaped, so the
    only ``<pre>`` and ``<table>`` tags are the renderer's)."""
    md = MarkdownIt("commonmark", {"html": False, "linkify": False}).enable("table")
    html = md.render(participant_markdown(text))
    return _scrolling(_scrolling(html, "pre", "Example"), "table", "Table")
