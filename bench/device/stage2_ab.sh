#!/usr/bin/env bash
# Stage-2 quality A/B of two code versions on one stage-1 model, in one call on a machine of four
# GPUs: the current tree (into $BUILD) against .oldsrc (into build-old). A shortened stage-1 model
# (6,000 fine steps, current tree, GPU 0), then uniform and adaptive stage 2 (1,200 steps, seed
# 6666) with each build at once (old on GPUs 0-1, new on 2-3), each evaluated on the test views.
#   bench/device/stage2_ab.sh OUT_DIR   -> OUT_DIR/stage2_ab.tgz (train and eval JSON), summary on stdout
source "$(dirname "$0")/common.sh"
out=$1
OLD=build-old
models=out/ab2
mkdir -p "$out" "$models"
jobs=$(( $(nproc) / 2 ))
build_tree . "$BUILD" "$jobs" atex_cli > out/build_new.log 2>&1 &
new_build=$!
build_old "$jobs" > out/build_old.log 2>&1 &
old_build=$!
wait "$new_build" || { tail -5 out/build_new.log; exit 1; }
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1 | tee "$out/gpu.txt"
train_short_stage1 "$models" 0
wait "$old_build" || { tail -5 out/build_old.log; exit 1; }
gpu=0
for bin in "$OLD" "$BUILD"; do
  for textures in uniform adaptive; do
    name=$models/${bin}_$textures
    (CUDA_VISIBLE_DEVICES=$gpu "$bin/bin/atex" train --data "$bb" --stage 2 --init "$models/stage1.atex" \
       --textures "$textures" --set stage2.iterations=1200 --out "$name.atex" --json > "$name.train.json" \
       2> "$name.log" &&
     CUDA_VISIBLE_DEVICES=$gpu "$bin/bin/atex" eval "$name.atex" --data "$bb" --json > "$name.eval.json") &
    gpu=$((gpu + 1))
  done
done
wait
tar czf "$out/stage2_ab.tgz" "$models"/*.json
python3 - "$models" "$OLD" "$BUILD" <<'PY'
import json, sys
models, builds = sys.argv[1], sys.argv[2:]
for b in builds:
    psnr = {t: json.load(open(f"{models}/{b}_{t}.eval.json"))["mean"]["psnr"] for t in ("uniform", "adaptive")}
    print(b, {t: round(v, 4) for t, v in psnr.items()}, "adaptive - uniform %+.3f dB" % (psnr["adaptive"] - psnr["uniform"]))
PY
