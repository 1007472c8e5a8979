#!/usr/bin/env bash
# Set up a virtual environment in .venv with MultiON installed (editable).
#   bash scripts/setup.sh          # simulator, server, client, baseline agents, report figures
#   bash scripts/setup.sh --dev    # + torch (CPU build), training extras, pytest and ruff
# Safe to run again: it reuses .venv and only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PYTHON" -m venv .venv
fi
PIP=(.venv/bin/python -m pip --disable-pip-version-check -q)
"${PIP[@]}" install --upgrade "pip>=23" >/dev/null
extras="[report]"
if [ "${1:-}" = "--dev" ]; then
  # torch first, pinned to the CPU build (a plain `torch` would pull several GB of CUDA wheels)
  "${PIP[@]}" install "torch==2.13.0"
  extras="[train,report,dev]"
fi
"${PIP[@]}" install -e ./client -e ".${extras}"
echo "MultiON installed in $(pwd)/.venv"
