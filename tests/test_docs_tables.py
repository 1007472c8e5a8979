"""Every Markdown table of the README and docs/ renders as a table (issue 42): a blank line
inside one ends it, and its remaining rows render as a paragraph of ``|`` on GitHub and on the
served guide. Rendered with the guide's own renderer (markdown-it-py, CommonMark with tables)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from markdown_it import MarkdownIt

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
_CELL_BORDER = re.compile(r"(?<!\\)\|")


def _renderer() -> MarkdownIt:
    return MarkdownIt("commonmark", {"html": False}).enable("table")


def stray_table_lines(text: str) -> list[int]:
    """Line numbers (from 1) of lines starting with ``|`` that are neither in a rendered table
    nor in a code block."""
    covered: set[int] = set()
    for token in _renderer().parse(text):
        if token.map is not None and token.type in ("table_open", "fence", "code_block"):
            covered.update(range(*token.map))
    return [
        number + 1
        for number, line in enumerate(text.splitlines())
        if line.lstrip().startswith("|") and number not in covered
    ]


def uneven_tables(text: str) -> list[tuple[int, list[int]]]:
    """(first line, cells per row) of rendered tables whose rows have different numbers of
    cells (the renderer drops the extra cells without a word)."""
    lines = text.splitlines()
    uneven = []
    for token in _renderer().parse(text):
        if token.type == "table_open" and token.map is not None:
            rows = lines[token.map[0] : token.map[1]]
            counts = [len(_CELL_BORDER.split(row.strip().strip("|"))) for row in rows]
            if len(set(counts)) > 1:
                uneven.append((token.map[0] + 1, counts))
    return uneven


def test_a_blank_line_inside_a_table_is_found() -> None:
    broken = "| a | b |\n| --- | --- |\n| 1 | 2 |\n\n| 3 | 4 |\n"
    assert stray_table_lines(broken) == [5]
    assert stray_table_lines(broken.replace("\n\n", "\n")) == []
    assert uneven_tables("| a | b |\n| --- | --- |\n| 1 | 2 | 3 |\n") == [(1, [2, 2, 3])]


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_table_of_the_docs_renders_whole(document: Path) -> None:
    text = document.read_text(encoding="utf-8")
    assert stray_table_lines(text) == [], f"{document.name}: rows outside any table"
    assert uneven_tables(text) == [], f"{document.name}: rows with a different number of cells"
