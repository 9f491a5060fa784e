#!/usr/bin/env bash
# The GPU experiments of BENCHMARKS.md, one phase per call (a lent GPU machine allows
# 10 minutes per command; the build folder and out/ persist between phases).
#   bench/device/paper_runs.sh build|lego|stage1|stage2|fit|matrix|build+matrix  OUT_DIR
# The matrix phases run bench/run_matrix.py with --out out/panoptic and a deadline that fits
# one call; rerun the same phase to continue (MATRIX_CONFIG picks the config, default
# bench/configs/panoptic_session.json; MATRIX_ARGS adds options, e.g. --only or --skip-fps).
# Data: .devdata (common.sh).
source "$(dirname "$0")/common.sh"
phase=$1 out=$2
mkdir -p "$out"
log() { echo "== $(date +%T) $*" >&2; }

case $phase in
  build)
    # PARITY=0: the CLI only (a change that leaves the CUDA code alone need not rerun the parity tests).
    targets="atex_cli"
    [ "${PARITY:-1}" = 0 ] || targets="$targets backend_parity_test deform_parity_test render_parity_test loss_parity_test"
    # shellcheck disable=SC2086  # the targets are words
    build_tree . "$BUILD" "$(nproc)" $targets 2>&1 | tail -3
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$out/gpu.txt"
    if [ "${PARITY:-1}" != 0 ]; then
      # All four parity tests, on the first GPU, with their measured errors kept.
      CUDA_VISIBLE_DEVICES=0 ctest --test-dir "$BUILD" -R parity --output-on-failure -V > "$out/parity.log" 2>&1 || true
      grep -E "tests passed|tests failed|\[deform parity\] forward positions|Failed|FAILED" "$out/parity.log" | tail -12
    fi
    ;;
  lego)
    # The embedded sample: a small deformation field (C 16, 32^3 x 13) so the asset is a few MB.
    log "lego: both stages"
    "$atex" train --data "$lego" --out out/lego.atex --json --time-limit "${LEGO_TIME:-240}" \
      --set stage1.init_points=20000 --set stage1.fine_iterations=8000 \
      --set stage1.deformation.grid.channels=16 --set 'stage1.deformation.grid.base_resolution=[32,32,32,13]' \
      --set stage2.iterations=2000 > "$out/lego.train.json" 2> "$out/lego.train.log"
    "$atex" info out/lego.atex > "$out/lego.info.txt"
    "$atex" fit out/lego.atex out/lego_2MiB.atex --budget 2MiB --data "$lego" --json \
      > "$out/lego.fit.json" 2> "$out/lego.fit.log"
    "$atex" eval out/lego_2MiB.atex --data "$lego" --json > "$out/lego_2MiB.eval.json"
    cp out/lego.atex out/lego_2MiB.atex "$out/"
    for f in out/lego.atex out/lego_2MiB.atex; do
      "$atex" render "$f" --data "$lego" --view test:0 --out "$out/$(basename "$f" .atex)_test0.png" \
        --ground-truth "$out/lego_gt_test0.png" >/dev/null 2>&1 || true
    done
    ;;
  stage1)
    log "basketball stage 1"
    "$atex" train --data "$bb" --out out/bb_s1.atex --stage 1 --json --profile \
      --time-limit "${STAGE1_TIME:-300}" --metrics "$out/bb_s1.metrics.csv" > "$out/bb_s1.train.json" 2> "$out/bb_s1.train.log"
    "$atex" info out/bb_s1.atex --json > "$out/bb_s1.info.json"
    for size in 640x360 1352x1014; do
      "$atex" fps out/bb_s1.atex --data "$bb" --size "$size" --json > "$out/none.fps.$size.json"
    done
    ;;
  stage2)
    log "basketball stage 2 matrix"
    bench/stage2_matrix.sh "$atex" "$bb" out/bb_s1.atex out/s2 --set "stage2.iterations=${STAGE2_ITERS:-1500}"
    cp out/s2/*.json "$out/" 2>/dev/null || true
    tail -n 5 out/s2/*.log > "$out/stage2_logs.txt" || true
    ;;
  fit)
    # Budgets at 25/50/100% of the uniform model's size, and 25/50% counts with the stage-1 order.
    uniform=$(stat -c %s out/s2/uniform.atex)
    for m in none uniform adaptive; do
      src=out/s2/$m.atex; [ $m = none ] && src=out/bb_s1.atex
      log "fit $m"
      timeout 200 "$atex" fit "$src" "out/fit_${m}_{}.atex" --budget "$((uniform / 4)),$((uniform / 2)),$uniform" \
        --data "$bb" --eval-views 0 --json > "$out/fit_$m.budget.json" 2> "$out/fit_$m.budget.log" || echo "fit $m failed" >&2
      for f in 0.25 0.5; do
        timeout 60 "$atex" fit "$src" "out/fit_${m}_count$f.atex" --keep-count $f --order-from out/bb_s1.atex \
          --data "$bb" --eval-views 0 --json > "$out/fit_$m.count$f.json" 2>> "$out/fit_$m.count.log" || echo "count $m $f failed" >&2
      done
    done
    ;;
  build+matrix)
    start=$(date +%s)
    "$0" build "$out"
    DEADLINE=$(( ${CALL_SECONDS:-570} - ($(date +%s) - start) )) "$0" matrix "$out"
    ;;
  matrix)
    rc=0
    python3 bench/run_matrix.py "${MATRIX_CONFIG:-bench/configs/panoptic_session.json}" --atex "$atex" \
      --out out/panoptic --deadline "${DEADLINE:-540}" ${MATRIX_ARGS:-} > "$out/matrix.log" 2>&1 || rc=$?
    echo "run_matrix exit $rc" | tee -a "$out/matrix.log"
    s1=out/panoptic/models/basketball/full/s6666/stage1.atex
    if [ -f "$s1" ] && [ ! -f out/panoptic/stage1_near0.01.eval.json ]; then
      # What the 0.2 near plane does: the same model with 3DGS's cull moved to 1 cm.
      "$atex" eval "$s1" --data "$bb" --near-plane 0.01 --json > out/panoptic/stage1_near0.01.eval.json 2>/dev/null || true
      for v in test:0 test:45; do
        "$atex" render "$s1" --data "$bb" --view $v --out "out/panoptic/stage1_${v/:/}.png" \
          --ground-truth "out/panoptic/gt_${v/:/}.png" >/dev/null 2>&1 || true
      done
    fi
    tar czf "$out/panoptic_results.tgz" --exclude='*.atex' --exclude='*.ckpt' out/panoptic 2>/dev/null || true
    ;;
  *) echo "unknown phase $phase" >&2; exit 2 ;;
esac
log "done $phase"
