#!/usr/bin/env bash
# Re-run the evaluation runs behind docs/baselines.md (one eval at a time, at low priority),
# then regenerate the doc's tables and figures from them:
#   bash scripts/run_baselines.sh RUNS_DIR [AGENT ...]    # default: all four agents
#   EPISODES_OVERRIDE=20 bash scripts/run_baselines.sh RUNS_DIR explorer   # other episode counts
#   EVAL_ARGS="--set camera.renderer=gl" bash scripts/run_baselines.sh RUNS_DIR explorer
#     (extra `multion eval` arguments for every run: gl plays explorer's 256² episodes ~6x faster
#     with the same metrics, docs/rendering.md; each run's metrics.json records them)
#   .venv/bin/multion report RUNS_DIR/* --out docs --doc baselines
# Each run writes RUNS_DIR/AGENT-Mon/, RUNS_DIR/AGENT-3on-distractors/ (the 3-ON variant with
# distractor objects) and RUNS_DIR/random-3on-budgetB/ (the found-budget table). Episode counts per agent are set below; random-oracle-found never calls a wrong FOUND,
# so the found-budget runs use `random`, which does.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:?usage: bash scripts/run_baselines.sh RUNS_DIR [AGENT ...]}
shift
read -r -a eval_args <<< "${EVAL_ARGS:-}"
multion=${MULTION:-.venv/bin/multion}
declare -A EPISODES=([random]=100 [random-oracle-found]=200 [oracle-planner]=100 [explorer]=50)
BUDGETS=(1 3 10)
agents=("$@")
[ ${#agents[@]} -gt 0 ] || agents=(random random-oracle-found oracle-planner explorer)

evaluate() {  # evaluate OUT_NAME EPISODES ARGS...
  local name=$1 episodes=$2 start
  shift 2
  if [ -f "$runs/$name/metrics.json" ]; then
    echo "$name: already in $runs (delete it to run again)"
    return
  fi
  start=$(date +%s)
  nice -n 15 $multion eval --split val --episodes "$episodes" --in-process --seed 0 \
    --out "$runs/$name" --quiet "${eval_args[@]}" "$@"
  echo "$name: $episodes episodes in $(( $(date +%s) - start )) s"
}

for agent in "${agents[@]}"; do
  n=${EPISODES_OVERRIDE:-${EPISODES[$agent]}}
  for m in 1 2 3; do
    evaluate "$agent-${m}on" "$n" --agent "$agent" --task "$m-on"
  done
  evaluate "$agent-3on-distractors" "$n" --agent "$agent" --task 3-on \
    --dataset server/multion/data/datasets/3-on-distractors/val.json.gz
  if [ "$agent" = random ]; then
    for budget in "${BUDGETS[@]}"; do
      evaluate "random-3on-budget$budget" "$n" --agent random --task 3-on \
        --set "task.found_budget=$budget"
    done
  fi
done
