#!/usr/bin/env bash
# The one-hour learning run of docs/learned.md: train AGENT on 1-ON on this CPU machine (same
# budget and seeds for every agent), then evaluate it on 100 val episodes, with sampled and with
# the most likely actions, and random-oracle-found on the same episodes.
#   bash scripts/learn_one_hour.sh [AGENT] [OUT] [TRAIN ARGS...]  # default: oracle-map in runs/learn-AGENT
#   bash scripts/learn_one_hour.sh no-map          # the same recipe without a map
#   bash scripts/learn_one_hour.sh oracle-map runs/learn-v3 \
#     --pretrain-map 1200 --episodes-per-scene 5   # the v3 recipe: learns on today's houses
#   bash scripts/learn_one_hour.sh oracle-map runs/learn-curriculum \
#     --curriculum 200000:4 --curriculum 440000:10  # near goals first (docs/learned.md)
#   .venv/bin/multion report runs/learn-oracle-map/eval-* runs/learn-no-map/eval-val100-stochastic \
#     --out runs/learn-report                      # paired differences on the same episodes
# An interrupted run resumes where its last checkpoint (every 10 updates) left off.
set -euo pipefail
cd "$(dirname "$0")/.."
agent=${1:-oracle-map}
out=${2:-runs/learn-$agent}
shift $(( $# < 2 ? $# : 2 ))
resume=(); [ -f "$out/checkpoint.pt" ] && resume=(--resume)
.venv/bin/multion train --agent "$agent" --task 1-on --frames 720000 --envs 8 \
  --image-size 36 --max-steps 500 --episodes-per-scene 200 --set maps.ego_size=25 \
  --set task.slack_reward=0 --found-prior 0.02 \
  --eval-every 240000 --eval-episodes 10 --out "$out" "${resume[@]}" "$@"
for mode in stochastic deterministic; do
  flag=(); [ "$mode" = deterministic ] && flag=(--deterministic)
  .venv/bin/multion eval --agent "$agent" --checkpoint "$out/checkpoint.pt" "${flag[@]}" \
    --task 1-on --split val --episodes 100 --workers 2 --seed 0 --out "$out/eval-val100-$mode"
done
[ -f "$out/eval-val100-random-oracle-found/metrics.json" ] ||
  .venv/bin/multion eval --agent random-oracle-found --task 1-on --split val --episodes 100 \
    --workers 2 --seed 0 --out "$out/eval-val100-random-oracle-found"
