#!/usr/bin/env bash
# Re-run the baseline table of docs/baselines.md (one eval at a time, at low priority).
#   bash scripts/run_baselines.sh [AGENT ...]     # default: all four agents
# Episode counts per agent are those of the table; each run writes runs/baselines/AGENT-Mon/.
set -euo pipefail
cd "$(dirname "$0")/.."
declare -A EPISODES=([random]=1000 [random-oracle-found]=1000 [oracle-planner]=200 [explorer]=100)
agents=("$@")
[ ${#agents[@]} -gt 0 ] || agents=(oracle-planner explorer random random-oracle-found)
for agent in "${agents[@]}"; do
  for m in 3 2 1; do
    start=$(date +%s)
    nice -n 15 .venv/bin/multion eval --agent "$agent" --task "$m-on" --split val \
      --episodes "${EPISODES[$agent]}" --in-process --seed 0 \
      --out "runs/baselines/$agent-${m}on" --quiet
    echo "$agent $m-on: ${EPISODES[$agent]} episodes in $(( $(date +%s) - start )) s"
  done
done
