#!/usr/bin/env bash
# A/B of the rasteriser on a lent GPU machine in one call: the current tree (into $BUILD) against
# .oldsrc (`git archive COMMIT | tar -x -C .oldsrc`, into build-old), on a shortened Panoptic model
# trained here (stage 1 with 6,000 fine steps, then 1,200 adaptive stage-2 steps), alternating old and
# new twice per model and size on GPU 1 while GPU 0 runs the parity tests of the current tree.
#   bench/device/raster_ab.sh OUT_DIR   -> OUT_DIR/{gpu.txt,parity.log,fps_ab.jsonl,ab_*.json}
source "$(dirname "$0")/common.sh"
out=$1
OLD=build-old
models=out/ab
mkdir -p "$out" "$models"
compact() { python3 -c 'import json, sys; print(json.dumps(json.load(sys.stdin)))'; }

(cmake -S .oldsrc -B "$OLD" -DCMAKE_BUILD_TYPE=Release -DATEX_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=90 \
   -DATEX_TESTS=OFF -DATEX_BENCHMARKS=OFF && cmake --build "$OLD" -j "$(nproc)" --target atex_cli) \
  > out/build_old.log 2>&1 &
old_build=$!
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DATEX_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=90 >/dev/null
cmake --build "$BUILD" -j "$(nproc)" --target atex_cli render_parity_test backend_parity_test deform_parity_test \
  loss_parity_test 2>&1 | tail -1
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$out/gpu.txt"
(CUDA_VISIBLE_DEVICES=0 ctest --test-dir "$BUILD" -R parity --output-on-failure -V > "$out/parity.log" 2>&1) &
parity=$!

if [ ! -f "$models/adaptive.atex" ]; then
  CUDA_VISIBLE_DEVICES=1 "$atex" train --data "$bb" --stage 1 --out "$models/stage1.atex" --json \
    --set stage1.fine_iterations=6000 > "$out/ab_stage1.json" 2> out/ab_stage1.log
  CUDA_VISIBLE_DEVICES=1 "$atex" train --data "$bb" --stage 2 --init "$models/stage1.atex" --textures adaptive \
    --set stage2.iterations=1200 --out "$models/adaptive.atex" --json > "$out/ab_adaptive.json" 2> out/ab_adaptive.log
fi
wait "$old_build" || { tail -5 out/build_old.log; exit 1; }
for model in stage1 adaptive; do
  for size in 640x360 1352x1014; do
    for bin in "$OLD" "$BUILD" "$OLD" "$BUILD"; do
      fps=$(CUDA_VISIBLE_DEVICES=1 "$bin/bin/atex" fps "$models/$model.atex" --data "$bb" --view test:0 \
        --size "$size" --repeats 100 --json | compact)
      echo "{\"build\": \"$bin\", \"model\": \"$model\", \"size\": \"$size\", \"fps\": $fps}" >> "$out/fps_ab.jsonl"
    done
  done
done
wait "$parity" || true
grep -E "tests passed|tests failed|\[render parity\]|\[backend parity\]|Failed|FAILED" "$out/parity.log" | tail -20
python3 - "$out/fps_ab.jsonl" <<'PY'
import json, sys, collections
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    r = json.loads(line)
    runs[(r["model"], r["size"], r["build"])].append(r["fps"].get("fps"))
for key in sorted(runs):
    print(*key, runs[key])
PY
