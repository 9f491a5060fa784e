#!/usr/bin/env bash
# A/B of the rasteriser on a lent machine of several GPUs in one call: the current tree (into $BUILD)
# against .oldsrc (`git archive COMMIT | tar -x -C .oldsrc`, into build-old) and against optional
# variants of the current tree, on a shortened Panoptic model trained here on GPU 0 (stage 1 with
# 6,000 fine steps, then 1,200 adaptive stage-2 steps). FPS runs alternate the builds twice per model
# and size on GPU 1; the parity tests of the current tree run on GPU 2 (and of each variant on GPU 3).
#   bench/device/raster_ab.sh OUT_DIR   -> OUT_DIR/{gpu.txt,parity*.log,fps_ab.jsonl,ab_*.json}
# AB_MODEL_DIR: use its stage1.atex and adaptive.atex instead of training (e.g. a run_matrix model
# folder); AB_PARITY=0 skips the parity tests.
# Variants: AB_VARIANTS="name ..." with a script out/probe/NAME.sh each, run inside a copy of the
# current tree (e.g. a sed that swaps one function) before that copy is built into build-NAME.
source "$(dirname "$0")/common.sh"
out=$1
OLD=build-old
models=${AB_MODEL_DIR:-out/ab}
mkdir -p "$out" "$models"
compact() { python3 -c 'import json, sys; print(json.dumps(json.load(sys.stdin)))'; }
jobs=$(( $(nproc) / 2 ))

build_tree . "$BUILD" "$jobs" atex_cli render_parity_test backend_parity_test deform_parity_test \
  loss_parity_test 2>&1 | tail -1
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$out/gpu.txt"

if [ ! -f "$models/adaptive.atex" ]; then
  (train_short_stage1 "$models" 0 && cp "$models/stage1.train.json" "$out/ab_stage1.json" &&
   CUDA_VISIBLE_DEVICES=0 "$atex" train --data "$bb" --stage 2 --init "$models/stage1.atex" --textures adaptive \
     --set stage2.iterations=1200 --out "$models/adaptive.atex" --json > "$out/ab_adaptive.json" 2> out/ab_adaptive.log) &
  train=$!
fi
parity=
if [ "${AB_PARITY:-1}" != 0 ]; then
  (CUDA_VISIBLE_DEVICES=2 ctest --test-dir "$BUILD" -R parity --output-on-failure -V > "$out/parity.log" 2>&1) &
  parity=$!
fi

# The other builds, in parallel with the training (half the cores each for old and the variants).
while pgrep -f "cmake --build build-old" >/dev/null; do sleep 2; done  # parallel_session's background build
build_old "$jobs" > out/build_old.log 2>&1 &
builds=("$!")
variant_builds=()
for name in ${AB_VARIANTS:-}; do
  src=out/variant_$name
  rm -rf "$src" && mkdir -p "$src"
  tar -c --exclude='./build*' --exclude=./bg --exclude=./out --exclude=./.devdata --exclude=./.oldsrc \
    --exclude=./.git . | tar -x -C "$src"
  (cd "$src" && bash "../../out/probe/$name.sh")
  build_tree "$src" "build-$name" "$jobs" atex_cli render_parity_test backend_parity_test \
    > "out/build_$name.log" 2>&1 &
  builds+=("$!")
  variant_builds+=("build-$name")
done
for b in "${builds[@]}"; do wait "$b" || { tail -5 out/build_*.log; exit 1; }; done
for name in ${AB_VARIANTS:-}; do
  [ "${AB_PARITY:-1}" = 0 ] && continue
  CUDA_VISIBLE_DEVICES=3 ctest --test-dir "build-$name" -R "render_parity|backend_parity" --output-on-failure -V \
    > "$out/parity_$name.log" 2>&1 || true
done &
variant_parity=$!
[ -n "${train:-}" ] && { wait "$train" || { tail -5 out/ab_*.log; exit 1; }; }

for model in stage1 adaptive; do
  list=("$OLD" "$BUILD")
  [ $model = adaptive ] && list+=("${variant_builds[@]}")
  for size in 640x360 1352x1014; do
    for round in 1 2; do
      for bin in "${list[@]}"; do
        fps=$(CUDA_VISIBLE_DEVICES=1 "$bin/bin/atex" fps "$models/$model.atex" --data "$bb" --view test:0 \
          --size "$size" --repeats 100 --json | compact)
        echo "{\"build\": \"$bin\", \"model\": \"$model\", \"size\": \"$size\", \"fps\": $fps}" >> "$out/fps_ab.jsonl"
      done
    done
  done
done
[ -n "$parity" ] && { wait "$parity" || true; }
wait "$variant_parity" || true
for log in $(ls "$out"/parity*.log 2>/dev/null); do
  echo "== $log"
  grep -E "tests passed|tests failed|\[backend parity\]|Failed|FAILED" "$log" | tail -8
  grep -E "\[parity\]" "$log" | head -5 | cut -c1-400
done
python3 - "$out/fps_ab.jsonl" <<'PY'
import json, sys, collections
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    r = json.loads(line)
    runs[(r["model"], r["size"], r["build"])].append(round(r["fps"].get("fps"), 1))
for key in sorted(runs):
    print(*key, runs[key])
PY
