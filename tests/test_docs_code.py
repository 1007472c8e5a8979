"""Every code block of the README and the docs site runs, or says why it does not (issue 52).

The blocks are found and run by mktestdocs (``grab_code_blocks``, ``check_md_file`` with an
executor registered per language), so a renamed option or function fails here, not a reader.
A fenced block is one of:

* ``bash`` / ``python``: run, page by page, in a fresh directory that holds a link to this
  environment as ``.venv`` (so ``.venv/bin/multion`` is the installed one), an empty
  ``docs/img`` (the pictures the pages regenerate land there, not in the repository) and the
  files the page writes first (below). A page's Python blocks run in one namespace, in order; each
  ``bash`` block in its own ``bash -euo pipefail``, in that directory, with a time limit;
* ``python title="NAME.py"``: a file the page's commands use, written to NAME.py first (it runs
  when they import it);
* ``bash title="Not run by the tests: REASON"`` (or ``python``): not run, the reason shown to
  the reader above the block (Material for MkDocs shows a code block's title);
* ``text`` / ``toml`` / ``sh`` (an output, a diagram, a file's content): not code to run.

docs/leaderboard.md's blocks are run by the tests that serve its challenge
(``RUN_ELSEWHERE``). The only edit made to a block before it runs: the remote-agent example's
episodes are cut to 30 steps (a random walker would otherwise walk the task's 2,500), and its
URL becomes the test server's.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

mktestdocs = pytest.importorskip("mktestdocs", reason="the docs extra: pip install -e '.[docs]'")

from markdown_it import MarkdownIt  # noqa: E402

from multion.api.local_server import LocalServer  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
REPORTS = ROOT / "docs" / "learned"  # reports `multion report` writes beside published runs
DOCUMENTS = [
    ROOT / "README.md",
    *sorted(p for p in (ROOT / "docs").rglob("*.md") if REPORTS not in p.parents),
]
RUN_ELSEWHERE = {
    "docs/leaderboard.md": "tests/leaderboard/test_docs_commands.py runs its bash blocks; "
    "test_lanes.py and test_habitat_starters.py its Python examples",
}
NOT_RUN = re.compile(r'^(bash|python) title="Not run by the tests: (?P<reason>[^"]{10,})"$')
FILE = re.compile(r'^python title="(?P<name>[a-z_]+\.py)"$')
NOT_CODE = {"text", "toml", "sh"}
BLOCK_TIMEOUT_S = 600
LOCAL_URL = "http://127.0.0.1:8000"
SHORT_EPISODES = ('{"num_goals": 3}', '{"num_goals": 3, "max_steps": 30}')


def fences(text: str) -> list[str]:
    """The info string of every fenced code block (CommonMark, as GitHub and the site read)."""
    return [t.info.strip() for t in MarkdownIt("commonmark").parse(text) if t.type == "fence"]


def kind(info: str) -> str:
    """``run``, ``file``, ``not run`` or ``not code``; ``ValueError`` for anything else."""
    if info in ("bash", "python"):
        return "run"
    if FILE.match(info):
        return "file"
    if NOT_RUN.match(info):
        return "not run"
    if info in NOT_CODE:
        return "not code"
    raise ValueError(f"code block ```{info}: neither runnable nor marked not runnable")


def name(path: Path) -> str:
    return str(path.relative_to(ROOT))


def test_kinds_of_blocks() -> None:
    assert kind("bash") == "run" and kind("python") == "run"
    assert kind('python title="my_agent.py"') == "file"
    assert kind('bash title="Not run by the tests: hours of training"') == "not run"
    for unmarked in ("", 'bash title="Not run by the tests: "', "console", "py", 'bash title="x"'):
        with pytest.raises(ValueError):
            kind(unmarked)
    # mktestdocs runs exactly the blocks marked `bash` / `python`, none of the others
    text = '```bash\necho 1\n```\n\n```bash title="Not run by the tests: a reason"\nexit 1\n```\n'
    assert mktestdocs.grab_code_blocks(text, lang="bash") == ["echo 1\n"]


@pytest.mark.parametrize("document", DOCUMENTS, ids=name)
def test_every_block_runs_or_says_why_not(document: Path) -> None:
    for info in fences(document.read_text(encoding="utf-8")):
        kind(info)  # raises for an unmarked block


def runnable_pages() -> Iterator[Path]:
    for document in DOCUMENTS:
        if name(document) in RUN_ELSEWHERE:
            continue
        infos = fences(document.read_text(encoding="utf-8"))
        if any(kind(info) == "run" for info in infos):
            yield document


@pytest.fixture(scope="module")
def server() -> Iterator[str]:
    with LocalServer(workers=1) as running:
        yield running.url


def bash_executor(directory: Path) -> Callable[[str], None]:
    venv = Path(sys.prefix)
    env = {**os.environ, "PATH": f"{venv / 'bin'}:{os.environ['PATH']}"}

    def run(source: str) -> None:
        done = subprocess.run(
            ["bash", "-euo", "pipefail", "-c", source], cwd=directory, env=env,
            capture_output=True, text=True, timeout=BLOCK_TIMEOUT_S,
        )  # fmt: skip
        assert done.returncode == 0, (
            f"{source}\nfailed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
        )

    return run


def python_executor(directory: Path, url: str) -> Callable[[str], None]:
    namespace: dict[str, object] = {"__name__": "__main__"}

    def run(source: str) -> None:
        if LOCAL_URL in source:
            assert SHORT_EPISODES[0] in source, "the remote-agent example changed: update this test"
            source = source.replace(LOCAL_URL, url).replace(*SHORT_EPISODES)
        cwd = Path.cwd()
        os.chdir(directory)
        try:
            exec(compile(source, "docs-block", "exec"), namespace)  # noqa: S102
        finally:
            os.chdir(cwd)

    return run


@pytest.mark.slow
@pytest.mark.parametrize("document", list(runnable_pages()), ids=name)
def test_the_pages_code_runs(
    document: Path, server: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    text = document.read_text(encoding="utf-8")
    (tmp_path / ".venv").symlink_to(Path(sys.prefix), target_is_directory=True)
    (tmp_path / "docs" / "img").mkdir(parents=True)  # pictures the pages regenerate go there
    for info in fences(text):
        match = FILE.match(info)
        if match:
            (blocks,) = [mktestdocs.grab_code_blocks(text, lang=info)]
            (tmp_path / match["name"]).write_text(blocks[0])
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(mktestdocs.__main__._executors, "bash", bash_executor(tmp_path))
    monkeypatch.setitem(mktestdocs.__main__._executors, "python", python_executor(tmp_path, server))
    mktestdocs.check_md_file(document, lang="python", memory=True)
    mktestdocs.check_md_file(document, lang="bash")
