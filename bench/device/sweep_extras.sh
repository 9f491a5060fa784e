#!/usr/bin/env bash
# Follow-ups of bench/configs/panoptic_stage1_sweep.json (run with --out out/sweep):
#   bench/device/sweep_extras.sh build-old   build .oldsrc (e.g. `git archive COMMIT`) into $ATEX_OLD_BUILD
#   bench/device/sweep_extras.sh renders     test views 0 (camera 0, t 0) and 45 (camera 10, t 11) of every
#                                            stage-1 model of the sweep, next to the ground truth
#   bench/device/sweep_extras.sh ab          FPS of the old build against the current one, alternating twice,
#                                            on the default stage-1 and adaptive models, on GPU $AB_GPU (default 0)
# Everything lands in out/sweep/extras (parallel_session.sh packs out/sweep).
source "$(dirname "$0")/common.sh"
OLD=${ATEX_OLD_BUILD:-build-old}  # git-ignored, like $BUILD
extras=out/sweep/extras
mkdir -p "$extras"
compact() { python3 -c 'import json, sys; print(json.dumps(json.load(sys.stdin)))'; }

case $1 in
  build-old)
    BUILD_TREE_OPTIONS="-DATEX_TESTS=OFF -DATEX_BENCHMARKS=OFF" build_tree .oldsrc "$OLD" "$(nproc)" atex_cli 2>&1 |
      tail -1
    ;;
  renders)
    for model in out/sweep/models/basketball/*/s6666/stage1.atex; do
      variant=$(basename "$(dirname "$(dirname "$model")")")
      for view in test:0 test:45; do
        "$atex" render "$model" --data "$bb" --view "$view" --out "$extras/${variant}_${view/:/}.png" \
          --ground-truth "$extras/gt_${view/:/}.png" > /dev/null
      done
    done
    ;;
  ab)
    for model in stage1 adaptive; do
      for size in 640x360 1352x1014; do
        for bin in "$OLD" "$BUILD" "$OLD" "$BUILD"; do
          fps=$(CUDA_VISIBLE_DEVICES=${AB_GPU:-0} "$bin/bin/atex" fps "out/sweep/models/basketball/full/s6666/$model.atex" \
            --data "$bb" --view test:0 --size "$size" --repeats 100 --json | compact)
          echo "{\"build\": \"$bin\", \"model\": \"$model\", \"size\": \"$size\", \"fps\": $fps}" >> "$extras/fps_ab.jsonl"
        done
      done
    done
    ;;
  *) echo "unknown phase $1" >&2; exit 2 ;;
esac
