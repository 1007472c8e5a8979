"""Figures on the code's shape, for the boundaries issue's before/after notes.

Prints the first-party imports made inside functions and the longest functions of the
server and agents packages. Usage: ``python scripts/code_figures.py [--top N]``.
"""

from __future__ import annotations

import argparse
import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = (
    ROOT / "server" / "multion",
    ROOT / "agents" / "multion_agents",
    ROOT / "client" / "multion_client",
)
FIRST_PARTY = ("multion", "multion_agents", "multion_client")


@dataclass(frozen=True)
class Function:
    path: str
    name: str
    lines: int


def _is_first_party(node: ast.Import | ast.ImportFrom) -> bool:
    if isinstance(node, ast.ImportFrom):
        return node.level > 0 or (node.module or "").split(".")[0] in FIRST_PARTY
    return any(alias.name.split(".")[0] in FIRST_PARTY for alias in node.names)


def scan(path: Path) -> tuple[list[Function], list[str]]:
    tree = ast.parse(path.read_text(), filename=str(path))
    rel = str(path.relative_to(ROOT))
    functions: list[Function] = []
    local_imports: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            end = node.end_lineno or node.lineno
            functions.append(Function(rel, node.name, end - node.lineno + 1))
            for inner in ast.walk(node):
                if isinstance(inner, ast.Import | ast.ImportFrom) and _is_first_party(inner):
                    local_imports.append(f"{rel}:{inner.lineno} (in {node.name})")
    return functions, sorted(set(local_imports))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--top", type=int, default=10, help="how many of the longest functions to list"
    )
    args = parser.parse_args()
    functions: list[Function] = []
    local_imports: list[str] = []
    for package in PACKAGES:
        for path in sorted(package.rglob("*.py")):
            found, imports = scan(path)
            functions += found
            local_imports += imports
    print(f"function-level first-party imports: {len(local_imports)}")
    for line in local_imports:
        print(f"  {line}")
    print(f"longest functions (of {len(functions)}):")
    for function in sorted(functions, key=lambda f: -f.lines)[: args.top]:
        print(f"  {function.lines:4d}  {function.path}::{function.name}")


if __name__ == "__main__":
    main()
