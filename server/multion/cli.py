"""The ``multion`` command's old address, kept for console scripts installed before issue 32.

The command is :mod:`multion_agents.cli` (the composition root, in the top package; the
``multion`` entry point of ``pyproject.toml``). Environments installed earlier have a
``bin/multion`` that imports ``multion.cli:main``, and must keep working until they are
reinstalled (``pip install -e .``), e.g. a training run of ``scripts/central_comparison.sh``
that is under way. Nothing in this repository imports this module; it reaches up to the agents
only when called.
"""

from __future__ import annotations

import importlib
import sys


def main(argv: list[str] | None = None) -> int:
    command = importlib.import_module("multion_agents.cli")
    return int(command.main(argv))


if __name__ == "__main__":
    sys.exit(main())
