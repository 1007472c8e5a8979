#!/usr/bin/env bash
# A real training run (simulators included) on a GPU machine whose python has a CUDA torch but
# not this project's other dependencies (the lent machines of docs/training-speed.md: Python
# 3.12, no PyBullet wheel for it, no network). Two steps:
#   bash scripts/gpu_train.sh prepare                      # here: fills .devtrain/ (git-ignored)
#   OUT=dir SECONDS_LEFT=540 bash scripts/gpu_train.sh run TRAIN ARGS...   # there
# (PYTHON=... names the interpreter that has torch; python3 by default)
# prepare downloads the sources of this .venv's PyBullet (trimmed to what compiles: 6 MB) and
# scikit-fmm, and copies gymnasium. run builds both there (about 75 s on 16 cores), imports torch
# before PyBullet in every process (the other order crashed a source-built PyBullet with that
# machine's CUDA torch), runs `multion train TRAIN ARGS... --out /tmp/run` until SECONDS_LEFT
# from its start is nearly spent, and leaves progress.csv, pretrain_vision.csv and the checkpoint
# (in 15 MB parts: cat OUT/checkpoint.pt.part* > checkpoint.pt; OUT/checkpoint.sha256) in OUT.
set -euo pipefail
cd "$(dirname "$0")/.."
carry=.devtrain
case ${1:-} in
  prepare)
    grep -qx "/$carry/" .git/info/exclude 2>/dev/null || echo "/$carry/" >> .git/info/exclude
    rm -rf "$carry" && mkdir -p "$carry/site" "$carry/tmp"
    py=.venv/bin/python
    site=$($py -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
    cp -r "$site/gymnasium" "$site/farama_notifications" "$carry/site/"
    version() { $py -c "from importlib.metadata import version; print(version('$1'))"; }
    pybullet=pybullet-$(version pybullet) fmm=scikit_fmm-$(version scikit-fmm)
    $py -m pip download -q --no-deps --no-binary=:all: -d "$carry/tmp" "${pybullet/-/==}"
    # pip would build scikit-fmm's metadata (meson) to download it: take the file from the index
    $py - "$fmm" "$carry/tmp" <<'PY'
import re, sys, urllib.request
name, folder = sys.argv[1], sys.argv[2]
page = urllib.request.urlopen("https://pypi.org/simple/scikit-fmm/").read().decode()
url = re.findall(rf'href="([^"]+/{re.escape(name)}\.tar\.gz)[^"]*"', page)[0]
urllib.request.urlretrieve(url, f"{folder}/{name}.tar.gz")
PY
    tar xzf "$carry/tmp/$pybullet.tar.gz" -C "$carry/tmp"
    # its models and textures (160 MB) are not compiled; the default goals are cylinders
    find "$carry/tmp/$pybullet/examples/pybullet/gym" -type f ! -name '*.py' -delete
    tar czf "$carry/pybullet.tar.gz" -C "$carry/tmp" "$pybullet"
    mv "$carry/tmp/$fmm.tar.gz" "$carry/scikit-fmm.tar.gz"
    rm -rf "$carry/tmp"
    du -sh "$carry" ;;
  run)
    shift
    out=${OUT:-.} python=${PYTHON:-python3} start=$(date +%s)
    deadline=$((start + ${SECONDS_LEFT:-540} - 25))
    src=/tmp/gpu-train-src site=$PWD/$carry/site
    mkdir -p "$src" && tar xzf "$carry/pybullet.tar.gz" -C "$src" && tar xzf "$carry/scikit-fmm.tar.gz" -C "$src"
    nvidia-smi -L || true
    # scikit-fmm: two extension modules, compiled directly (its build needs meson-python)
    fmm=$(echo "$src"/scikit_fmm-*/skfmm) && mkdir -p "$site/skfmm" && cp "$fmm"/*.py "$site/skfmm/"
    inc=$("$python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
    np=$("$python" -c 'import numpy; print(numpy.get_include())')
    ext=$("$python" -c 'import sysconfig; print(sysconfig.get_config_var("EXT_SUFFIX"))')
    g++ -O2 -shared -fPIC -I"$inc" -I"$np" -I"$fmm" "$fmm"/{fmm,heap,base_marcher,distance_marcher,travel_time_marcher,extension_velocity_marcher}.cpp -o "$site/skfmm/cfmm$ext"
    g++ -O2 -shared -fPIC -I"$inc" -I"$fmm" "$fmm/pheap.cpp" "$fmm/heap.cpp" -o "$site/skfmm/pheap$ext"
    (cd "$src"/pybullet-* && "$python" -m pip install -q --no-index --no-deps --no-build-isolation \
      --no-compile --target "$site" . > "$out/build.log" 2>&1) || { tail -40 "$out/build.log"; exit 3; }
    echo "import torch  # before pybullet: see scripts/gpu_train.sh" > "$site/sitecustomize.py"
    export PYTHONPATH=$site:$PWD/server:$PWD/client:$PWD/agents PYTHONUNBUFFERED=1 PYTHONFAULTHANDLER=1
    echo "built in $(( $(date +%s) - start )) s; training for $((deadline - $(date +%s))) s"
    status=0
    timeout $((deadline - $(date +%s))) "$python" -m multion_agents.cli train "$@" --out /tmp/run \
      > "$out/train.log" 2>&1 || status=$?
    echo "train exit $status (124: the deadline)"; tail -c 600 "$out/train.log" | tr '\r' '\n' | tail -4
    cp /tmp/run/progress.csv /tmp/run/pretrain_vision.csv "$out/" 2>/dev/null || true
    if [ -f /tmp/run/checkpoint.pt ]; then
      split -b 15M -d /tmp/run/checkpoint.pt "$out/checkpoint.pt.part"
      (cd /tmp/run && sha256sum checkpoint.pt) > "$out/checkpoint.sha256"
    fi ;;
  *) echo "usage: $0 prepare | run TRAIN ARGS..." >&2; exit 2 ;;
esac
