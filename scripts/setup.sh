#!/usr/bin/env bash
# Set up a virtual environment in .venv with MultiON installed (editable).
#   bash scripts/setup.sh          # simulator, server, client, baseline agents, report figures
#   bash scripts/setup.sh --dev    # + torch (CPU build), training extras, videos, pytest and ruff, the docs site (mkdocs)
# Safe to run again: it reuses .venv and only installs what is missing.
# Then `source .venv/bin/activate` (or call .venv/bin/multion, .venv/bin/python).
#
# Python: pybullet publishes wheels for CPython 3.10 and 3.11 only, so this picks python3.11 or
# python3.10 when one is on the PATH (PYTHON=/path/to/python overrides). With a newer Python,
# pip compiles Bullet from source: it needs a C++ compiler and the Python headers
# (Debian: build-essential python3-dev) and takes about 10 minutes.
set -euo pipefail
cd "$(dirname "$0")/.."

python_version() { "$1" -c 'import sys; print("%d.%d" % sys.version_info[:2])'; }

if [ -z "${PYTHON:-}" ]; then
  for candidate in python3.11 python3.10 python3; do
    if command -v "$candidate" >/dev/null; then PYTHON=$candidate; break; fi
  done
fi
if [ ! -x .venv/bin/python ]; then
  version=$(python_version "${PYTHON:?no python3 found: install Python 3.10 or 3.11}")
  case "$version" in
    3.10|3.11) ;;
    3.[0-9]) echo "setup.sh: $PYTHON is Python $version; MultiON needs 3.10 or later (3.10 or 3.11 for pybullet's wheels)" >&2; exit 1 ;;
    *) echo "setup.sh: $PYTHON is Python $version, for which pybullet has no wheel: pip will compile" \
            "Bullet from source (a C++ compiler and Python headers, about 10 minutes). To avoid it," \
            "install Python 3.11 or 3.10 and run again (or PYTHON=/path/to/python3.11 bash scripts/setup.sh)." >&2 ;;
  esac
  "$PYTHON" -m venv .venv
fi
PIP=(.venv/bin/python -m pip --disable-pip-version-check -q)
# setuptools' editable builds (./client and .) each say "Editable installation. Please be careful
# with folders in your working directory ..." as a ten-line warning that pip shows even with -q:
# information, not a problem. Only that warning is left out: errors and other warnings still show.
export PYTHONWARNINGS="${PYTHONWARNINGS:+$PYTHONWARNINGS,}ignore:Editable installation"
"${PIP[@]}" install --upgrade "pip>=23" >/dev/null
extras="[report]"
if [ "${1:-}" = "--dev" ]; then
  # torch first, the CPU build: a plain `pip install torch` on Linux pulls several GB of CUDA
  # wheels. PyTorch's CPU wheel index when it answers, else the default index (mirrors, or
  # machines that reach only PyPI, where the default index decides which build comes).
  torch_cpu_index=https://download.pytorch.org/whl/cpu
  if .venv/bin/python -c 'import torch' 2>/dev/null; then
    :
  elif .venv/bin/python - "$torch_cpu_index/torch/" <<'EOF'
import sys
import urllib.request

try:
    urllib.request.urlopen(sys.argv[1], timeout=15)
except OSError:
    sys.exit(1)
EOF
  then
    "${PIP[@]}" install "torch==2.13.0" --index-url "$torch_cpu_index"
  else
    echo "setup.sh: $torch_cpu_index cannot be reached; torch comes from the default index" >&2
    "${PIP[@]}" install "torch==2.13.0"
  fi
  extras="[train,report,video,dev,docs]"
fi
"${PIP[@]}" install -e ./client -e ".${extras}"
echo "MultiON installed in $(pwd)/.venv: source .venv/bin/activate (or call .venv/bin/multion)"
