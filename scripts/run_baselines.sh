#!/usr/bin/env bash
# Re-run the baseline table of docs/baselines.md (one eval at a time, at low priority).
#   bash scripts/run_baselines.sh [AGENT ...]     # default: all four agents
#   RUNS=/somewhere bash scripts/run_baselines.sh  # output folder (default runs/baselines)
# Episode counts per agent are those of the table; each run writes $RUNS/AGENT-Mon/, and the
# 3-ON distractor variant $RUNS/AGENT-3on-distractors/.
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${RUNS:-runs/baselines}
declare -A EPISODES=([random]=1000 [random-oracle-found]=1000 [oracle-planner]=100 [explorer]=30)
agents=("$@")
[ ${#agents[@]} -gt 0 ] || agents=(random random-oracle-found oracle-planner explorer)
for agent in "${agents[@]}"; do
  for m in 3 2 1; do
    start=$(date +%s)
    nice -n 15 .venv/bin/multion eval --agent "$agent" --task "$m-on" --split val \
      --episodes "${EPISODES[$agent]}" --in-process --seed 0 \
      --out "$RUNS/$agent-${m}on" --quiet
    echo "$agent $m-on: ${EPISODES[$agent]} episodes in $(( $(date +%s) - start )) s"
  done
  start=$(date +%s)
  nice -n 15 .venv/bin/multion eval --agent "$agent" --task 3-on --split val \
    --dataset server/multion/data/datasets/3-on-distractors/val.json.gz \
    --episodes "${EPISODES[$agent]}" --in-process --seed 0 \
    --out "$RUNS/$agent-3on-distractors" --quiet
  echo "$agent 3-on-distractors: ${EPISODES[$agent]} episodes in $(( $(date +%s) - start )) s"
done
