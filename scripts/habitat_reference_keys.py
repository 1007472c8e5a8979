"""Write the MultiON reference's habitat config keys as this project's data (issue 53 item 2).

The habitat ``Config`` of the light client (:mod:`multion_client.habitat_config`) holds every key
of the reference's default config tree, so that agents written for the MultiON challenges read
what they read there. The trees are the yacs defaults of three reference files (each executed
with a stand-in for yacs that records the keys; nothing else of the reference runs):

* ``chal_2022``: 3dlg-hcvc/multion-challenge, branch ``chal_2022``, ``habitat/config/default.py``
  (the MultiON 2022 starter's habitat);
* ``main_old``: 3dlg-hcvc/multion-challenge, branch ``main``, ``multion/config/default_old.py``
  (the same tree with the 2023 additions: semantic map sensors, ...);
* ``saimwani``: saimwani/multiON, ``habitat/config/default.py`` (the paper's code, the 2021
  challenge's habitat; the ``chal-2021`` branch of multion-challenge ships no config).

The ``main`` branch's ``multion/config/default.py`` is habitat 0.2.5's hydra config (lower-case
``habitat.task...`` keys, 2024), a schema the starters of 2021 and 2022 never read: not covered.

Two files are written: the served defaults (``client/multion_client/habitat_defaults.json``: each
key once, its value from the first tree above that has it, with the file and line it comes from),
and the test's fixture (``tests/data/habitat_reference_keys.json``: each tree's keys and values as
the reference has them). Run with the reference repositories fetched as git directories:

    .venv/bin/python scripts/habitat_reference_keys.py \\
        --multion-challenge /path/to/multion-challenge.git --saimwani /path/to/multiON.git
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DEFAULTS = ROOT / "client" / "multion_client" / "habitat_defaults.json"
FIXTURE = ROOT / "tests" / "data" / "habitat_reference_keys.json"

# a stand-in for yacs.config: a CfgNode that records its keys (the reference's default.py files
# import yacs and call clone() and merge_from_other_cfg() while building the tree)
YACS = textwrap.dedent(
    """
    import copy

    class CfgNode(dict):
        def __init__(self, *args, new_allowed=False, **kwargs):
            super().__init__(*args, **kwargs)

        def __getattr__(self, name):
            try:
                return self[name]
            except KeyError:
                raise AttributeError(name) from None

        def __setattr__(self, name, value):
            self[name] = value

        def clone(self):
            return copy.deepcopy(self)

        def merge_from_other_cfg(self, other):
            for key, value in other.items():
                if isinstance(value, dict) and isinstance(self.get(key), dict):
                    self[key].merge_from_other_cfg(value)
                else:
                    self[key] = copy.deepcopy(value)
    """
)


@dataclass(frozen=True)
class Tree:
    name: str
    repository: str
    branch: str
    path: str

    def source(self, commit: str) -> str:
        return f"{self.repository}@{commit[:12]} (branch {self.branch}) {self.path}"


TREES = (
    Tree("chal_2022", "3dlg-hcvc/multion-challenge", "chal_2022", "habitat/config/default.py"),
    Tree("main_old", "3dlg-hcvc/multion-challenge", "main", "multion/config/default_old.py"),
    Tree("saimwani", "saimwani/multiON", "main", "habitat/config/default.py"),
)
"""The reference trees, first wins where they give one key different values."""


def flat(node: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"A.B.C": value}`` of a nested tree (tuples as lists)."""
    out: dict[str, Any] = {}
    for key, value in node.items():
        path = f"{prefix}{key}"
        if isinstance(value, dict) and value:
            out.update(flat(value, f"{path}."))
        else:
            out[path] = {} if isinstance(value, dict) else value
    return json.loads(json.dumps(out))


def read_tree(source: str, yacs_dir: Path) -> dict[str, Any]:
    sys.path.insert(0, str(yacs_dir))
    try:
        scope: dict[str, Any] = {"__name__": "reference_config"}
        exec(compile(source, "reference_config", "exec"), scope)  # noqa: S102
    finally:
        sys.path.remove(str(yacs_dir))
        sys.modules.pop("yacs.config", None)
        sys.modules.pop("yacs", None)
    return flat(scope["_C"])


def line_of(path: str, lines: list[str]) -> int:
    """The line that sets ``path`` (``_C.A.B.C = ...``, or ``X.B.C = ...`` on a node assigned
    into the tree later), else the line that makes its nearest section."""
    parts = path.split(".")
    for end in range(len(parts), 0, -1):
        candidates = [r"_C\." + re.escape(".".join(parts[:end]))]
        candidates += [r"[A-Z_]+\." + re.escape(".".join(parts[s:end])) for s in range(1, end - 1)]
        for pattern in candidates:
            for number, line in enumerate(lines, start=1):
                if re.match(pattern + r"\s*=", line):
                    return number
    raise ValueError(f"no line sets {path}")


def git_show(gitdir: Path, branch: str, path: str) -> tuple[str, str]:
    commit = subprocess.run(
        ["git", "-C", str(gitdir), "rev-parse", branch], capture_output=True, text=True, check=True
    ).stdout.strip()
    text = subprocess.run(
        ["git", "-C", str(gitdir), "show", f"{commit}:{path}"],
        capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    return commit, text


def dump(document: dict[str, Any]) -> str:
    """JSON with one line per key of the innermost mappings (a reviewable diff)."""

    def block(value: Any, indent: str) -> str:
        if isinstance(value, dict) and value and set(value) != {"value", "from"}:
            inner = indent + "  "
            items = [f"{inner}{json.dumps(k)}: {block(v, inner)}" for k, v in value.items()]
            return "{\n" + ",\n".join(items) + f"\n{indent}}}"
        return json.dumps(value)  # a key's {"value", "from"}, a value

    return block(document, "") + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--multion-challenge", type=Path, required=True, help="its git directory")
    parser.add_argument("--saimwani", type=Path, required=True, help="multiON's git directory")
    args = parser.parse_args()
    gitdirs = {"3dlg-hcvc/multion-challenge": args.multion_challenge}
    gitdirs["saimwani/multiON"] = args.saimwani
    trees: dict[str, dict[str, Any]] = {}
    sources: dict[str, str] = {}
    served: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as stand_in:
        (Path(stand_in) / "yacs").mkdir()
        (Path(stand_in) / "yacs" / "__init__.py").write_text("")
        (Path(stand_in) / "yacs" / "config.py").write_text(YACS)
        for tree in TREES:
            commit, text = git_show(gitdirs[tree.repository], tree.branch, tree.path)
            sources[tree.name] = tree.source(commit)
            trees[tree.name] = read_tree(text, Path(stand_in))
            lines = text.splitlines()
            for path, value in trees[tree.name].items():
                if path not in served:
                    served[path] = {"value": value, "from": f"{tree.name}:{line_of(path, lines)}"}
    about = (
        "The MultiON reference's habitat config keys (scripts/habitat_reference_keys.py writes "
        "this file): "
    )
    defaults_about = about + (
        "each key's default from the first source that has it, 'from' naming the source and "
        "the line of its file that sets it (or makes its section). "
        "multion_client.habitat_config overrides what the track decides."
    )
    DEFAULTS.write_text(dump({"about": defaults_about, "sources": sources, "keys": served}))
    fixture = {"about": about + "every tree as the reference has it.", "sources": sources}
    FIXTURE.write_text(dump({**fixture, "trees": trees}))
    print(f"{len(served)} keys → {DEFAULTS.relative_to(ROOT)}, {FIXTURE.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
