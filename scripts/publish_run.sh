# Sourced by central_comparison.sh and recipe_pilot.sh, which set $multion. publish_run RUN KEPT
# copies an evaluation run's metrics.json and episodes.jsonl, and its training's progress.csv and
# pretrain_vision.csv where there are, into KEPT. The checkpoint's path in metrics.json keeps its
# part from runs/ on: a run made with an absolute OUT (from a worktree) would publish a path of
# its machine. RUN first gains the measures the task has added since it was evaluated (`multion
# rescore`), so that a run evaluated by older code never replaces a kept copy that has them; a
# run that does not replay (older than recorded actions) is kept as evaluated.
publish_run() {
  local run=$1 kept=$2
  $multion rescore --quiet "$run" ||
    echo "publish_run: $run kept as evaluated (multion rescore could not replay it)" >&2
  mkdir -p "$kept"
  sed -E 's#"checkpoint": "/[^"]*/(runs/[^"]*)"#"checkpoint": "\1"#' "$run/metrics.json" \
    > "$kept/metrics.json"
  cp "$run/episodes.jsonl" "$kept/"
  for log in progress.csv pretrain_vision.csv; do
    if [ -f "$run/../$log" ]; then cp "$run/../$log" "$kept/"; fi
  done
}
