#!/usr/bin/env bash
# Issue 51's pilot: which training options make `no-map` learn? The central comparison's recipe
# (scripts/central_comparison.sh: 1-ON, 8 envs, 36², training episodes of 500 steps, no slack
# penalty, FOUND prior 0.02, seed 1) at 500k frames, once as the paper's recipe and once with
# each option beyond it alone and all together, then 100 val episodes each (sampled actions,
# seed 0) and a paired report. Resumable like the central comparison: run it again and finished
# runs are skipped, an interrupted training continues from its checkpoint.
#   bash scripts/recipe_pilot.sh                       # every run, in the order below
#   ONLY="no-map-all no-map-paper" bash scripts/recipe_pilot.sh
#   OUT=runs/pilot FRAMES=500000 AGENT=no-map bash scripts/recipe_pilot.sh
#   AGENT=proj-neural-map ONLY=proj-neural-map-found-head-all bash scripts/recipe_pilot.sh
#                                                      # the learn-to-see options on a learned map
# For AGENT=obj-recog-map every run adds --balanced-recognition, as the learn-to-see recipe does.
#   PUBLISH=1 bash scripts/recipe_pilot.sh             # keep the runs in docs/learned/pilot
#   IMAGE_SIZE=128 RENDERER=gl ONLY=no-map-found-head-all-128-gl bash scripts/recipe_pilot.sh
#                                                      # a run at another image size or renderer
# IMAGE_SIZE (default 36) and RENDERER (camera.renderer of training and evaluation; default the
# config's, tiny) name a variant: its runs' names end in -SIZE and -RENDERER, as the central
# comparison's variants do, so they never resume a 36² run.
# To keep working in the tree while it runs, run it from a copy (see central_comparison.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-runs/pilot}
frames=${FRAMES:-500000}
agent=${AGENT:-no-map}
episodes=${EPISODES:-100}
only=${ONLY:-}
multion=${MULTION:-.venv/bin/multion}
published=docs/learned/pilot
source scripts/camera_variant.sh  # image_size, renderer, camera_variant, camera
source scripts/publish_run.sh     # publish_run
# The FOUND curriculum covers the first 40 % of the run. `all` has the reference's penalty
# (2.5: saimwani/multiON environments.py l. 82-83); with it the agent stopped calling FOUND at
# all, so `found` alone tries a fifth of it (FOUND_PENALTY).
found_frames=$((frames * 2 / 5))
found_penalty=${FOUND_PENALTY:-0.5}
recipe=(--task 1-on --frames "$frames" --envs 8 --image-size "$image_size" --max-steps 500
  --episodes-per-scene 200 --set task.slack_reward=0 --found-prior 0.02 --no-tensorboard --quiet
  "${camera[@]}")
# the checkpoint gives the evaluation its image size
evaluation=(--task 1-on --split val --episodes "$episodes" --workers 2 --seed 0 "${camera[@]}")

wanted() { [ -z "$only" ] || [[ " $only " == *" $1 "* ]]; }

# pilot NAME [OPTIONS...]: $out/NAME/checkpoint.pt, then $out/NAME/eval-val
pilot() {
  local name=$1$camera_variant
  local dir=$out/$name
  shift
  wanted "$name" || return 0
  [ -f "$dir/eval-val/metrics.json" ] && { echo "done: $name"; return; }
  local resume=()
  [ -f "$dir/checkpoint.pt" ] && resume=(--resume)
  local extra=()
  [ "$agent" != obj-recog-map ] || extra=(--balanced-recognition)
  echo "== train $name ($agent, $frames frames) $(date -u +%FT%TZ)"
  $multion train --agent "$agent" "${recipe[@]}" --out "$dir" "${resume[@]}" "${extra[@]}" "$@"
  echo "== eval $name $(date -u +%FT%TZ)"
  rm -rf "$dir/eval-val"
  $multion eval --agent "$agent" --checkpoint "$dir/checkpoint.pt" "${evaluation[@]}" \
    --out "$dir/eval-val"
}

pilot "$agent-all" --found-curriculum "$found_frames:2.5" --goal-heads --pretrain-vision 2000
pilot "$agent-paper"
pilot "$agent-heads" --goal-heads
pilot "$agent-found-sup" --found-supervision 1
pilot "$agent-found" --found-curriculum "$found_frames:$found_penalty"
pilot "$agent-vision" --pretrain-vision 2000
# FOUND supervision with both curricula: near goals first (`--curriculum`: within 4 m until 40 %
# of the frames, 10 m until 70 %), and wrong FOUNDs that cost FOUND_PENALTY without ending
# training episodes until 40 % (`--found-curriculum`). Alone, the supervision saw almost no
# step at a goal; with near goals only, the policy it taught called FOUND everywhere at first
# and its episodes ended on wrong FOUNDs within 5 steps, before any goal was reached.
pilot "$agent-found-sup-curricula" --found-supervision 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --found-curriculum "$found_frames:$found_penalty"
# With 1, P(FOUND) at the goal fell 0.05 -> 0.015 over 180k frames as the penalty taught
# "never FOUND" faster than the supervision taught where: ten times the supervision.
pilot "$agent-found-sup10-curricula" --found-supervision 10 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --found-curriculum "$found_frames:$found_penalty"
# FOUND decided by a supervised head, not by the actor (--found-head): PPO teaches only the
# movements, so nothing teaches "never FOUND"; the gate opens where the head is more sure than
# not that FOUND succeeds with the goal in view. Near goals first, so that such steps are common.
pilot "$agent-found-head-near" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10"
# The head pretrained too: vision pretraining teaches it on the rendered frames (the policy's
# first step; FOUND would succeed within the success distance) before PPO.
pilot "$agent-found-head-vision" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --pretrain-vision 2000
# The same with wrong FOUNDs free (no penalty, no end) until 40 % of the frames, so that the
# gate's early mistakes do not end training episodes: 25 % val Success (docs/learn-to-see.md).
pilot "$agent-found-head-free" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --pretrain-vision 2000 --found-curriculum "$found_frames:0"
# The same with the goal heads and vision pretraining (29 %: the learn-to-see recipe). Its
# movement policy stayed near a random walk's. At 36² a goal 2-3 m away covers a median 6 pixels
# (63 at 128², `multion bench --only goal-pixels`), so the goal heads may have too little to
# see: IMAGE_SIZE=128 RENDERER=gl runs it as no-map-found-head-all-128-gl. Result: 40 % val
# Success, every episode that came within reach won (25 of 40 at 36²), no more of them reached
# (docs/learn-to-see.md, "At 128²: the FOUND head sees").
pilot "$agent-found-head-all" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000
# Its train Success fell from 36 % to 4 % when the goals moved from 4 m to 10 m: the same with
# goals farther by smaller steps (4 m until 20 % of the frames, 7 m until 40 %, 10 m until 55 %,
# 15 m until 70 %).
pilot "$agent-found-head-smooth" --found-head 1 --goal-heads --pretrain-vision 2000 \
  --curriculum "$((frames / 5)):4" --curriculum "$found_frames:7" \
  --curriculum "$((frames * 11 / 20)):10" --curriculum "$((frames * 7 / 10)):15"
# The head fired on 2 % of the val steps where the goal shows within reach, where a balanced
# linear probe of its input finds them (ROC AUC 0.987, scripts/found_head_probe.py): the
# learn-to-see options with the head's positive steps weighed 10 times.
pilot "$agent-found-head-weighted" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
  --found-head-positive-weight 10
# It came within 1.5 m of the goal in 40 of 100 val episodes of 2500 steps (`multion
# diagnose`): the learn-to-see options with an exploration bonus for new ground (Ye et al.
# 2021's coverage reward, 0.25 per step, decaying, learned/coverage.py).
pilot "$agent-found-head-coverage" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
  --coverage-reward 0.25
# At 0.25 the bonus changed neither Success nor the ground searched (10.8 cells of 44), and the
# movement policy stayed near uniform (entropy 0.97 of at most 1.10 over three movements): ten
# times the bonus, so that new ground outweighs the distance reward to a goal not yet seen.
# On no-map it looped more decisively: without a map it does not know where it has been. With
# a map (without the bonus, proj-neural-map at 128² walked into walls on half of its forward
# steps, no-map on 30 %): AGENT=proj-neural-map IMAGE_SIZE=128 RENDERER=gl
# ONLY=proj-neural-map-found-head-coverage-2.5-128-gl. Result: 10.3 cells per episode against
# 6.7, within reach in 40 episodes against 35, but 33 % val Success against 32 % (+1 [-9, +11])
# and a lower SPL (docs/learn-to-see.md); not kept.
pilot "$agent-found-head-coverage-2.5" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
  --coverage-reward 2.5
# Evaluation plays 2500 steps and 65 of its 100 episodes end there; training episodes stop at
# 500 (and their end counts as terminal), so the policy never learns a search past step 500:
# the learn-to-see options with training episodes as long as evaluation's.
pilot "$agent-found-head-long" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 --max-steps 2500
# Its movement policy stayed near uniform (entropy 1.00 of at most 1.10 over three movements,
# 0.80-0.94 with the paper's recipe), and its gradient norm before clipping was 2-4, against
# 0.3-0.5 with the paper's recipe: the heads' losses outweigh PPO's on the shared GRU (measured
# since: gru_gradient_* in progress.csv, docs/learn-to-see.md). The reference does not normalise
# advantages (saimwani/multiON ppo_multinav.yaml l. 44); normalised, PPO's term has unit scale
# beside the heads' and the entropy bonus. Result: movements more decisive (entropy 0.78-0.88),
# 22 % val Success against 29 %; the recipe stays as it is.
pilot "$agent-found-head-normalized" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
  --normalize-advantages
# Even then the policy's gradient on the shared GRU stayed 1/3 to 1/16 of the value loss's and
# mostly far below the goal heads' (gru_gradient_* at 500k frames): the GRU learns what the
# critic and the heads need. Adam scales each weight's step by its own gradient's size, so the
# value and goal heads' own weights learn as fast with smaller weights; only the shared trunk
# (encoder, GRU) hears the policy louder: the learn-to-see options with the value loss and
# each goal head weighted a fifth (0.5 -> 0.1, 0.25 -> 0.05). Result: the policy's share of the
# GRU's gradient rose to 14-19 %, train Success per 100k frames stayed the recipe's, 20 % val
# Success against 29 % (docs/learn-to-see.md); the recipe stays as it is.
pilot "$agent-found-head-policy-share" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
  --value-coef 0.1 --goal-head-coef 0.05
# Imitation with a teacher the learner can follow: DAgger labels from the `explorer` baseline
# (frontier search on a map it builds from the learner's own RGB-D and pose, then the goal once
# its colour shows; --expert explorer), where the oracle planner's labels walked to goals the
# learner had not seen (docs/learn-to-see.md: 2 % train Success). With the actor calling FOUND (no
# head) the run stopped at 107k frames: episodes ended on a wrong FOUND after ~100 steps and
# train Success stayed at 5 % with goals within 4 m (the recipe's: 34-39 %). So the learn-to-see
# options, FOUND by the head, and the explorer's movements taught to the actor (its FOUND labels
# teach nothing: ppo.py).
pilot "$agent-found-head-explorer-imitation" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
  --imitation-coef 1 --expert explorer
# More houses. Every pilot above drew a new train house only every 200 episodes (as the paper
# recipe's runs): 500k frames of 8 envs at ~330 steps an episode are ~190 episodes per env, so
# each trained in 8 of the 61 train houses at a time (new draws at each curriculum stage and
# resume: the reset seed is the seed's and the update's), so about 24 houses in all, the same
# ones for the runs that went uninterrupted. The v3 recipe's oracle-map changed house every 5
# episodes (docs/learn-to-see.md). The learn-to-see options with a new house every 5 episodes.
pilot "$agent-found-head-houses" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
  --episodes-per-scene 5
# The agent's pose. Failures are mostly episodes that never come within reach: the policy
# walks in loops (docs/learn-to-see.md, "How they move"), and nothing it reads says where it has
# been. The task serves GPS and compass (the reference's multinav_mp3d.yaml l. 35), which its
# policies do not read; habitat-lab's ObjectNav baseline does (resnet_policy.py l. 487, 520).
# The learn-to-see options with the GRU reading the pose (--pose-input).
pilot "$agent-found-head-pose" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 --pose-input
# A critic on its own GRU. The value loss's gradient on the shared GRU was 3 to 16 times the
# policy's, and weighting it a fifth (`policy-share`) changed nothing; separate networks avoid
# that interference (Cobbe et al. 2021, Phasic Policy Gradient, abstract). The learn-to-see
# options with the critic reading its own GRU over the same inputs, detached (--separate-critic).
# Result: 29 % val Success, the recipe's own (paired +0 [-10, +10], docs/learn-to-see.md); not kept.
pilot "$agent-found-head-separate-critic" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 --separate-critic
# obj-recog-map's recogniser, trained only during PPO, answered on 42 % of the val frames showing
# the goal within 1.5 m where a linear probe of the same embedding answered on 86 % (`multion
# diagnose`): the learn-to-see options with the recogniser also learning on vision pretraining's
# frames. Only for AGENT=obj-recog-map (IMAGE_SIZE=128 RENDERER=gl: its 128² pilot had 21 %).
# Result: 26 % (+5 [-3, +13]), SPL +4.4 [+0.6, +9.0]; within reach in 41 episodes (28), its
# FOUND head missing 15 of them (docs/learn-to-see.md).
if [ "$agent" = obj-recog-map ]; then
  pilot "$agent-found-head-recogniser" --found-head 1 --curriculum "$found_frames:4" \
    --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
    --pretrain-recogniser
fi
# obj-recog-map's FOUND head, on the GRU alone, missed 15 of the 41 episodes that came within
# reach (no-map's missed none at 128²); its GRU also reads the map, and vision pretraining taught
# the head at episode starts, with the map empty. The head reading the frame's embedding too
# (--found-head-reads-image), on no-map (the control) and on obj-recog-map with the recogniser.
# Result (128², gl): no-map 39 % (-1 [-12, +10], SPL +6.4 [+0.8, +12.6]); obj-recog-map 21 %
# (-5 [-14, +4]), its head missing 17 of 38 episodes within reach. Not kept (docs/learn-to-see.md).
pilot "$agent-found-head-image" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
  --found-head-reads-image
if [ "$agent" = obj-recog-map ]; then
  pilot "$agent-found-head-recogniser-image" --found-head 1 --curriculum "$found_frames:4" \
    --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
    --pretrain-recogniser --found-head-reads-image
fi
# Those 15 misses all ended at the step limit, 11 within 0.25 m of the goal: a goal underfoot is
# out of the camera's view, and the head's label (within reach and in view) says "not here". The
# head labelled wherever the goal is within reach and has been in view this episode
# (--found-head-label seen), on obj-recog-map with the recogniser, and on no-map (the control).
# Result (128², gl): obj-recog-map 29 % (+3 [-6, +12]), winning 29 of the 34 episodes within
# reach (15 misses there before), but within reach less often; -11 [-22, 0] against no-map.
# no-map with the label: 32 % (-8 [-19, +3] against the in-view label); not kept.
if [ "$agent" = obj-recog-map ]; then
  pilot "$agent-found-head-recogniser-seen" --found-head 1 --curriculum "$found_frames:4" \
    --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
    --pretrain-recogniser --found-head-label seen
fi
pilot "$agent-found-head-seen" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 \
  --found-head-label seen
# The learned maps write the image encoder's features (proj-neural-map its spatial features,
# obj-recog-map its recogniser's answers on them), which PPO changes under the map as it goes:
# the learn-to-see options with the pretrained encoder frozen (--freeze-vision), on any agent
# (AGENT=proj-neural-map for the map; no-map as the control). Cheaper updates too: the rollout
# keeps the frozen encoder's outputs (multion bench --only learner --learner-freeze-vision).
# Result (128², gl): proj-neural-map 22 % (-10 [-20, 0] against unfrozen), no-map 29 % (-11
# [-23, 0]); the map against no-map, both frozen, -7 [-17, +3]. Not kept (docs/learn-to-see.md).
pilot "$agent-found-head-frozen" --found-head 1 --curriculum "$found_frames:4" \
  --curriculum "$((frames * 7 / 10)):10" --goal-heads --pretrain-vision 2000 --freeze-vision
# Every option together, FOUND supervision included (it came after `all`, from `multion diagnose`).
pilot "$agent-all-sup" --found-curriculum "$found_frames:2.5" --goal-heads --pretrain-vision 2000 \
  --found-supervision 1

mapfile -t runs < <(find "$out" -path '*/eval-val/metrics.json' -printf '%h\n' | sort)
[ "${#runs[@]}" -gt 0 ] && $multion report "${runs[@]}" --out "$out/report"
if [ "${PUBLISH:-0}" = 1 ]; then
  for run in "${runs[@]}"; do
    publish_run "$run" "$published/$(basename "$(dirname "$run")")"
  done
  mapfile -t kept_runs < <(find "$published" -name metrics.json -printf '%h\n' | sort)
  $multion report "${kept_runs[@]}" --out "$published/report"
fi
