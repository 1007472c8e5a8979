#!/usr/bin/env bash
# Where should a FOUND head's gate open? (issue 51). The learn-to-see runs call FOUND where the
# head's probability exceeds 0.5, and most of their wrong FOUNDs come 1.5-1.9 m from the goal,
# just beyond the success distance: the head is unsure there, and walking on costs little. A
# higher gate cannot be read off played episodes (`multion diagnose` reads lower ones), so
# this plays the checkpoint at each gate on episodes of the *train* houses (a dataset made here,
# seed 51), never the val episodes it is reported on, and writes a paired report. Pick the gate
# there, then evaluate it once on val:
#   CHECKPOINT=runs/central-128-gl-learn-to-see-720k/no-map/checkpoint.pt AGENT=no-map \
#     RENDERER=gl bash scripts/found_gate_sweep.sh
#   GATES="0.5 0.7 0.9" EPISODES=60 OUT=runs/gate/no-map ...      # the defaults
# Resumable: a gate already played is skipped.
set -euo pipefail
cd "$(dirname "$0")/.."
checkpoint=${CHECKPOINT:?give CHECKPOINT=path/to/checkpoint.pt}
agent=${AGENT:?give AGENT, the agent of the checkpoint (no-map, proj-neural-map, ...)}
gates=${GATES:-0.5 0.7 0.9}
episodes=${EPISODES:-60}
out=${OUT:-runs/gate/$(basename "$(dirname "$checkpoint")")}
multion=${MULTION:-.venv/bin/multion}
source scripts/camera_variant.sh  # camera: the --set arguments of RENDERER
dataset=runs/gate/train-1on-$episodes.json.gz
mkdir -p "$out" "$(dirname "$dataset")"
[ -f "$dataset" ] || $multion dataset generate --task 1-on --split train --episodes "$episodes" \
  --seed 51 --out "$dataset"
played=()
for gate in $gates; do
  dir=$out/gate-$gate
  played+=("$dir")
  [ -f "$dir/metrics.json" ] && { echo "done: gate $gate"; continue; }
  echo "== gate $gate $(date -u +%FT%TZ)"
  rm -rf "$dir"
  $multion eval --agent "$agent" --checkpoint "$checkpoint" --task 1-on --split train \
    --dataset "$dataset" --seed 0 --workers 2 --found-gate "$gate" "${camera[@]}" --quiet \
    --out "$dir"
done
# one agent on the same episodes: the report's paired table compares every two gates
$multion report "${played[@]}" --out "$out/report" --no-figures
