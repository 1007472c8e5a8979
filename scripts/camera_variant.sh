# Sourced by central_comparison.sh, recipe_pilot.sh and found_gate_sweep.sh: IMAGE_SIZE (default
# 36) and RENDERER (camera.renderer of training and evaluation; default the config's, tiny) name a
# variant of a run, "-SIZE" then "-RENDERER" (36² and tiny add nothing). `multion report` strips
# that suffix to pair a run with the one it varies (Run.label_besides_camera in report/runs.py).
# Sets image_size, renderer, camera_variant and camera (the --set arguments for train and eval).
image_size=${IMAGE_SIZE:-36}
renderer=${RENDERER:-}
camera_variant=""
[ "$image_size" = 36 ] || camera_variant="-$image_size"
[ -z "$renderer" ] || [ "$renderer" = tiny ] || camera_variant="$camera_variant-$renderer"
camera=()
[ -z "$renderer" ] || camera=(--set "camera.renderer=$renderer")
