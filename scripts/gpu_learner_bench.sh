#!/usr/bin/env bash
# `multion bench --only learner` on a GPU machine whose python has a CUDA torch but not this
# project's other dependencies (the lent machines of docs/learned.md: Python 3.12, no PyBullet,
# no network). Two steps:
#   bash scripts/gpu_learner_bench.sh prepare [BEFORE]  # here: fills .devcarry/ (git-ignored)
#   OUT=dir bash scripts/gpu_learner_bench.sh run       # there, with .devcarry/ carried along
# (PYTHON=... names the interpreter that has torch; python3 by default)
# prepare copies gymnasium from this machine's .venv and writes import-only stand-ins for
# PyBullet and scikit-fmm (the learner bench never simulates); with BEFORE (a commit), `run`
# also times that commit's learner code, in the same run, for a before/after ratio.
set -euo pipefail
cd "$(dirname "$0")/.."
carry=.devcarry
agents="${AGENTS:-no-map,oracle-map,oracle-ego-map,proj-neural-map,obj-recog-map}"
case ${1:-} in
  prepare)
    grep -qx "/$carry/" .git/info/exclude 2>/dev/null || echo "/$carry/" >> .git/info/exclude
    rm -rf "$carry" && mkdir -p "$carry/site" "$carry/skfmm"
    site=$(.venv/bin/python -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
    cp -r "$site/gymnasium" "$site/farama_notifications" "$carry/site/"
    cat > "$carry/pybullet.py" <<'PY'
"""Import-only stand-in (the learner bench never simulates): calling anything fails."""


class _Missing(int):
    def __call__(self, *args, **kwargs):
        raise RuntimeError("pybullet is not installed on this machine (import-only stand-in)")


def __getattr__(name):
    return _Missing(0)
PY
    cp "$carry/pybullet.py" "$carry/pybullet_data.py"
    cp "$carry/pybullet.py" "$carry/skfmm/__init__.py"
    if [ -n "${2:-}" ]; then
      mkdir -p "$carry/before"
      git archive "$2" agents/multion_agents | tar -x -C "$carry/before" --strip-components=1
      cp agents/multion_agents/bench/learner.py "$carry/before/multion_agents/bench/"
      echo "$2" > "$carry/before/COMMIT"
    fi
    du -sh "$carry" ;;
  run)
    out=${OUT:-.} python=${PYTHON:-python3}
    base=$PWD/$carry:$PWD/$carry/site:$PWD/server:$PWD/client
    nvidia-smi -L || true
    "$python" -c "import torch; print('torch', torch.__version__, 'cores', __import__('os').cpu_count())"
    codes=(after); [ -d "$carry/before" ] && codes=(before after)
    for device in cuda cpu; do
      for code in "${codes[@]}"; do
        path=$PWD/agents; [ "$code" = before ] && path=$PWD/$carry/before
        echo "== $device, $code ($path)" | tee -a "$out/learner.txt"
        PYTHONPATH=$base:$path "$python" -c "
from multion_agents.bench.learner import learner_settings, run_learner_bench
run_learner_bench(learner_settings('$agents', 3, '$device'))" 2>&1 | tee -a "$out/learner.txt"
      done
    done ;;
  *) echo "usage: $0 prepare [BEFORE_COMMIT] | run" >&2; exit 2 ;;
esac
