#!/usr/bin/env bash
# The paper's central comparison (map vs no map, Table 3 at 1-ON) at the reference's defaults
# (50-cell oracle crop, goals as 3 x 3 cells, depth 0-10 m, 768-unit GRU) on the version 3
# houses, with the one-hour recipe's budget: 720k frames per agent, the same seeds, then 100 val
# episodes each with sampled actions (as the reference's `_eval_checkpoint`,
# habitat_baselines/rl/ppo/ppo_trainer.py l. 629 and 1430 of saimwani/multiON: deterministic=False)
# and a paired report. Resumable: run it again and finished steps are skipped, an interrupted
# training continues from its last checkpoint (every 10 updates). A run already published in
# docs/learned/central/NAME (PUBLISH=1 below) counts as done, so a fresh clone goes on from there.
#   bash scripts/central_comparison.sh                 # every stage, in the order below
#   STAGES="core" bash scripts/central_comparison.sh   # only the first four agents
#   OUT=runs/central FRAMES=720000 bash scripts/central_comparison.sh
#   MULTION='python -m multion_agents.cli' ...             # another installation of the command
#   PUBLISH=1 bash scripts/central_comparison.sh       # then docs/learned.md's tables (below)
#   IMAGE_SIZE=128 RENDERER=gl bash scripts/central_comparison.sh   # issue 44's 128² variant
#   ONLY="no-map oracle-map proj-neural-map" ...       # only these runs of the stages
#   RECIPE=learn-to-see STAGES="core learned" ...      # issue 51's recipe, beyond the paper
#   RECIPE=learn-to-see FRAMES=720000 ...              # at the paper runs' budget: runs/central-learn-to-see-720k
# IMAGE_SIZE (default 36) and RENDERER (camera.renderer of training and evaluation; default the
# config's, tiny) make a variant with its own OUT (runs/central-128-gl above) and its own
# published runs (docs/learned/central-128-gl): the 36² runs are never restored into it. Its
# report also reads the published 36² runs (paired intervals, 128² against 36²; a recipe at 128²
# also the 128² paper-recipe runs and its own 36² runs), and PUBLISH=1
# keeps its runs and writes that report to docs/learned/central-128-gl/report, leaving
# docs/learned.md's tables to the 36² runs.
# Stages, in this order by default: core (oracle-map, no-map, oracle-ego-map,
# random-oracle-found), shapes (NoMap with the supplement's shapes as goals), pretrain
# (oracle-map after map pretraining), learned (proj-neural-map, obj-recog-map). The report goes
# to $OUT/report (`multion report`).
# Each evaluation and stage starts new processes that import the tree's code as it is then: to
# keep working in a tree while this runs, run it from a copy you leave alone, e.g.
#   git worktree add --detach ../central-tree HEAD && cd ../central-tree &&
#   PYTHONPATH=$PWD/server:$PWD/client:$PWD/agents MULTION=$OLDPWD/.venv/bin/multion \
#     OUT=$OLDPWD/runs/central bash scripts/central_comparison.sh
# RECIPE (default paper) picks the training options: `paper`, the paper's PPO; `learn-to-see`,
# issue 51's options beyond the paper for every agent, those of its pilot's best no-map run
# (`no-map-found-head-all`, docs/learn-to-see.md: 29 % val Success at 500k frames against the paper
# recipe's 2 %): FOUND decided by a supervised head, pretrained with the image encoder on
# rendered frames; Marza et al.'s goal heads; goals within 4 m until 200k frames and 10 m until
# 350k, as in the pilot (its train Success at 4 m levelled off within 100k frames, so the rest
# of the 3M trains on the task's goals); and the balanced, pretrained recogniser for
# obj-recog-map; 3M
# frames by default; a recipe other than the paper's is a variant of its own
# (runs/central-learn-to-see, docs/learned/central-learn-to-see). At 128² with gl its pilot
# reached 40 % (its FOUND head sees the goal there; docs/learn-to-see.md), so it also runs as
#   RECIPE=learn-to-see FRAMES=720000 IMAGE_SIZE=128 RENDERER=gl ...  # runs/central-128-gl-learn-to-see-720k
# FOUND_GATE=G (a recipe with the FOUND head only): each trained run NAME is also played on the
# same val episodes with the head's gate at G as the run NAME-gate-G, paired with NAME in the
# report (`--pair`). Choose G on train houses first (scripts/found_gate_sweep.sh), never on val.
set -euo pipefail
cd "$(dirname "$0")/.."
recipe_name=${RECIPE:-paper}
options=()
case $recipe_name in
  paper) frames=${FRAMES:-720000} ;;
  learn-to-see)
    frames=${FRAMES:-3000000}
    options=(--found-head 1 --goal-heads --pretrain-vision 2000
      --curriculum 200000:4 --curriculum 350000:10) ;;
  *) echo "unknown RECIPE $recipe_name (paper, learn-to-see)" >&2; exit 2 ;;
esac
found_gate=${FOUND_GATE:-}
if [ -n "$found_gate" ] && [ "$recipe_name" = paper ]; then
  echo "FOUND_GATE is for a recipe with the FOUND head (RECIPE=learn-to-see)" >&2; exit 2
fi
source scripts/camera_variant.sh  # image_size, renderer, camera_variant, camera
source scripts/publish_run.sh     # publish_run
# the published 36² runs are the comparison's reference; any other size or renderer is a variant
variant=$camera_variant
[ "$recipe_name" = paper ] || variant="$variant-$recipe_name"
# a recipe beyond the paper's at other than its 3M frames (FRAMES=720000: the paper recipe's
# budget, for paired runs at equal frames) is a variant of its own too: -720k, -1M, -1500000
if [ "$recipe_name" != paper ] && [ "$frames" != 3000000 ]; then
  if [ $((frames % 1000000)) = 0 ]; then variant="$variant-$((frames / 1000000))M"
  elif [ $((frames % 1000)) = 0 ]; then variant="$variant-$((frames / 1000))k"
  else variant="$variant-$frames"; fi
fi
published=docs/learned/central$variant
recipe_variant=${variant#"$camera_variant"}
out=${OUT:-runs/central$variant}
episodes=${EPISODES:-100}
stages=${STAGES:-core shapes pretrain learned}
only=${ONLY:-}  # run names; empty: every run of the stages
multion=${MULTION:-.venv/bin/multion}
recipe=(--task 1-on --frames "$frames" --envs 8 --image-size "$image_size" --max-steps 500
  --episodes-per-scene 200 --set task.slack_reward=0 --found-prior 0.02 --no-tensorboard
  "${camera[@]}")
# the checkpoint gives the evaluation its image size; the renderer is the machine's choice
evaluation=(--task 1-on --split val --episodes "$episodes" --workers 2 --seed 0 "${camera[@]}")

# restore_published NAME: a run kept in $published/NAME becomes $out/NAME/eval-val
restore_published() {
  local kept=$published/$1 dir=$out/$1
  [ -f "$kept/metrics.json" ] && [ ! -f "$dir/eval-val/metrics.json" ] || return 0
  mkdir -p "$dir/eval-val"
  cp "$kept/metrics.json" "$kept/episodes.jsonl" "$dir/eval-val/"
  if [ -f "$kept/progress.csv" ]; then cp "$kept/progress.csv" "$dir/"; fi
  echo "restored: $1 (published in $kept)"
}

# wanted NAME: whether ONLY (if set) names this run
wanted() { [ -z "$only" ] || [[ " $only " == *" $1 "* ]]; }

# train_and_eval NAME AGENT [TRAIN ARGS...]: $out/NAME/checkpoint.pt, then $out/NAME/eval-val
train_and_eval() {
  local name=$1 agent=$2 dir=$out/$1
  shift 2
  wanted "$name" || return 0
  restore_published "$name"
  if [ -f "$dir/eval-val/metrics.json" ]; then
    echo "done: $name"
    eval_at_gate "$name" "$agent"
    return
  fi
  local resume=()
  [ -f "$dir/checkpoint.pt" ] && resume=(--resume)
  echo "== train $name ($agent, $frames frames) $(date -u +%FT%TZ)"
  local extra=("${options[@]}")
  if [ "$recipe_name" != paper ] && [ "$agent" = obj-recog-map ]; then
    # its recogniser pretrained on rendered frames too: in the 128² pilots it brought the goal
    # into view +15 [+7, +24] more often and SPL +4.4 [+0.6, +9.0] (docs/learn-to-see.md)
    extra+=(--balanced-recognition --pretrain-recogniser)
  fi
  $multion train --agent "$agent" "${recipe[@]}" --out "$dir" "${resume[@]}" "${extra[@]}" "$@"
  echo "== eval $name $(date -u +%FT%TZ)"
  rm -rf "$dir/eval-val"
  $multion eval --agent "$agent" --checkpoint "$dir/checkpoint.pt" "${evaluation[@]}" \
    --out "$dir/eval-val"
  eval_at_gate "$name" "$agent"
}

# eval_at_gate NAME AGENT: with FOUND_GATE, $out/NAME's checkpoint played at that gate as
# $out/NAME-gate-G/eval-val
eval_at_gate() {
  [ -n "$found_gate" ] || return 0
  local name=$1-gate-$found_gate checkpoint=$out/$1/checkpoint.pt
  restore_published "$name"
  [ -f "$out/$name/eval-val/metrics.json" ] && { echo "done: $name"; return; }
  [ -f "$checkpoint" ] || { echo "skipped: $name (no $checkpoint to play)"; return; }
  echo "== eval $name $(date -u +%FT%TZ)"
  rm -rf "$out/$name/eval-val"
  $multion eval --agent "$2" --checkpoint "$checkpoint" "${evaluation[@]}" \
    --found-gate "$found_gate" --out "$out/$name/eval-val"
}

for stage in $stages; do
  case $stage in
    core)
      train_and_eval oracle-map oracle-map
      train_and_eval no-map no-map
      train_and_eval oracle-ego-map oracle-ego-map
      wanted random-oracle-found && restore_published random-oracle-found
      if wanted random-oracle-found && [ ! -f "$out/random-oracle-found/eval-val/metrics.json" ]; then
        $multion eval --agent random-oracle-found "${evaluation[@]}" \
          --out "$out/random-oracle-found/eval-val"
      fi ;;
    pretrain) train_and_eval oracle-map-pretrained oracle-map --pretrain-map 1200 ;;
    learned)
      train_and_eval proj-neural-map proj-neural-map
      train_and_eval obj-recog-map obj-recog-map ;;
    shapes) train_and_eval no-map-shapes no-map --set task.goal_set=shapes ;;
    *) echo "unknown stage $stage (core, pretrain, learned, shapes)" >&2; exit 2 ;;
  esac
done
mapfile -t runs < <(find "$out" -path '*/eval-val/metrics.json' -printf '%h\n' | sort)
# a variant is reported beside the published runs it varies: the 36² paper-recipe runs, and
# for a recipe at another camera those of its camera with the paper's recipe and those of its
# recipe at 36² (paired by name across cameras, by episode within one)
reference=()
if [ -n "$variant" ]; then
  for kept in docs/learned/central docs/learned/central$camera_variant \
      docs/learned/central$recipe_variant; do
    if [ "$kept" != "$published" ] && [ -d "$kept" ] && [[ " ${reference[*]} " != *" $kept "* ]]; then
      reference+=("$kept")
    fi
  done
fi
# gate_pairs RUN...: in `pairs`, `--pair` arguments for each run played at a FOUND gate
# (.../NAME-gate-G or .../NAME-gate-G/eval-val) and the same run at its own gate, where both are
gate_pairs() {
  pairs=()
  local run
  for run in "$@"; do
    if [[ $run =~ ^(.*)-gate-[0-9.]+(/eval-val)?$ ]] &&
        [ -f "${BASH_REMATCH[1]}${BASH_REMATCH[2]}/metrics.json" ]; then
      pairs+=(--pair "$run" "${BASH_REMATCH[1]}${BASH_REMATCH[2]}")
    fi
  done
}
gate_pairs "${runs[@]}"
$multion report "${runs[@]}" "${reference[@]}" "${pairs[@]}" --out "$out/report"
# PUBLISH=1: keep each evaluated run (metrics.json, episodes.jsonl, the training's progress.csv
# and pretrain_vision.csv, after `multion rescore`: scripts/publish_run.sh) in $published/NAME
# and regenerate the tables at the head of docs/learned.md (a variant: its report beside the 36²
# runs in $published/report)
if [ "${PUBLISH:-0}" = 1 ]; then
  for run in "${runs[@]}"; do
    publish_run "$run" "$published/$(basename "$(dirname "$run")")"
  done
  if [ -z "$variant" ]; then
    $multion report "$published" --out docs --doc learned
  else
    mapfile -t kept_runs < <(find "$published" -name metrics.json -printf '%h\n' | sort)
    gate_pairs "${kept_runs[@]}"
    $multion report "${kept_runs[@]}" "${reference[@]}" "${pairs[@]}" --out "$published/report"
  fi
fi
