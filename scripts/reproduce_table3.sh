#!/usr/bin/env bash
# Reproduce the paper's Table 3 (all agents, 1/2/3-ON, 40M frames each, test split), resumably;
# prints a time estimate per run first. Options: see `scripts/reproduce_table3.py --help`.
#   bash scripts/reproduce_table3.sh [--out runs/table3] [--estimate-only] ...
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/python scripts/reproduce_table3.py "$@"
