#!/usr/bin/env bash
# The one-hour learning run of docs/learned.md: train oracle-map on 1-ON on this CPU machine,
# then evaluate it and random-oracle-found on the same 100 val episodes.
#   bash scripts/learn_oracle_map.sh [OUT]      # default OUT: runs/learn-oracle-map
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/learn-oracle-map}
.venv/bin/multion train --agent oracle-map --task 1-on --frames 720000 --envs 8 \
  --image-size 36 --max-steps 500 --episodes-per-scene 200 --set maps.ego_size=25 \
  --set task.slack_reward=0 --found-prior 0.02 \
  --eval-every 240000 --eval-episodes 10 --out "$out"
for mode in stochastic deterministic; do
  flag=(); [ "$mode" = deterministic ] && flag=(--deterministic)
  .venv/bin/multion eval --agent oracle-map --checkpoint "$out/checkpoint.pt" "${flag[@]}" \
    --task 1-on --split val --episodes 100 --workers 2 --seed 0 --out "$out/eval-val100-$mode"
done
.venv/bin/multion eval --agent random-oracle-found --task 1-on --split val --episodes 100 \
  --workers 2 --seed 0 --out "$out/eval-val100-random-oracle-found"
