#!/usr/bin/env bash
# One GPU-machine session for issues 23 and 24, and a Panoptic model for issue 21's players.
# A lent machine allows 10 minutes per command; the steps run in the background (setsid) and
# outlive the call while the machine stays warm, so each next `wait` call must follow at once.
#   bench/device/issue23_24.sh start OUT   build, then start the steps
#   bench/device/issue23_24.sh wait OUT    follow them until they end or CALL_SECONDS (default 540) pass
# Every call leaves OUT/progress.txt, OUT/results.tgz (logs, tables, rows), OUT/corpus.tgz (fuzz
# inputs new since the start) and, once fitted, OUT/panoptic_stage1_15MiB.atex.
# Steps (logs in out/s23/):
#   1. (in the start call) the CUDA build (bg: CLI and tests) and .oldsrc's CLI (build-old); copies
#      under out/ of the fuzz kit, the corpus, the data and the lego sample
#   2. GPU: the CUDA tests (ctest -L cuda) beside the training of fit_panoptic.sh's short models
#      meanwhile (RANDOM_BUDGETS=1): bench/fit_random_budgets.sh -n 1000 on the lego sample (8
#      fits at a time, on the GPU: the fit's backend is auto), and (FUZZ=1) the fuzz campaign on
#      FUZZ_FIRST (fast targets, 6 processes)
#   3. fit_panoptic.sh on those models, old and new CLI, alone on the machine (timed); with
#      FIT15=1 the stage-1 model fitted to 15 MiB (issue 21: small enough to come back)
#   4. GPU: gpu_memory_stress.sh; CPU meanwhile (FUZZ=1): the fuzz campaign on the other targets
#      (14 processes)
source "$(dirname "$0")/common.sh"
phase=$1 out=$2
s=out/s23
mkdir -p "$out" "$s"
start=$(date +%s)
CALL_SECONDS=${CALL_SECONDS:-540}
RUNS=${FUZZ_RUNS:-10000000}
FUZZ_SECONDS=${FUZZ_SECONDS:-480}
FUZZ_FIRST=${FUZZ_FIRST:-fuzz_image,fuzz_npz,fuzz_ply,fuzz_spz,fuzz_exr,fuzz_splat,fuzz_compressed_ply,fuzz_transforms_json}
# The 1,000 random budgets and the fuzzing are done (BENCHMARKS.md, issues 23 and 24): off
# unless asked for (RANDOM_BUDGETS=1, FUZZ=1 with .fuzzkit and the corpus in the tree).
RANDOM_BUDGETS=${RANDOM_BUDGETS:-0}
FUZZ=${FUZZ:-0}

# Before the background starts (the next call replaces the source tree, its tracked files and
# the carried folders): both builds, and copies under out/ of what the steps read.
prepare() {
  if [ "$FUZZ" = 1 ]; then
    touch "$s/corpus.marker"
    rm -rf "$s/kit" "$s/corpus"
    mkdir -p "$s/kit"
    tar -C "$s/kit" -xJf .fuzzkit/kit.tar.xz
    cp -r tests/fuzz/corpus "$s/corpus"
  fi
  cp samples/lego_adaptive_2MiB.atex "$s/lego.atex"
  cp -r .devdata out/devdata
  (build_old 6 > "$s/build_old.log" 2>&1 || echo "build-old failed" >> "$s/steps.log") &
  cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DATEX_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=90 \
    -DATEX_DATA_DIR="$PWD/out/devdata" > "$s/build.log" 2>&1
  cmake --build "$BUILD" -j 16 >> "$s/build.log" 2>&1 || { echo "build failed" >> "$s/steps.log"; tail -20 "$s/build.log"; }
  wait
}

steps() {
  set +e
  local t0
  t0=$(date +%s)
  note() { echo "$(date +%T) [$(( $(date +%s) - t0 ))s] $*" >> "$s/steps.log"; }
  note "orchestrator started"
  export ATEX_SKIP_BUILD=1 ATEX_DEVDATA=out/devdata
  bb=out/devdata/panoptic_basketball
  fuzz() {  # LOG-NAME JOBS TARGETS
    LD_LIBRARY_PATH=$PWD/$s/kit/lib bench/fuzz_campaign.sh --prebuilt --build "$s/kit/build" --corpus "$s/corpus" \
      --jobs "$2" --seconds "$FUZZ_SECONDS" --runs "$RUNS" --targets "$3" --out "$s/$1" > "$s/$1.log" 2>&1
  }
  note "step 2: GPU tests and models | random budgets | fuzz $FUZZ_FIRST"
  # The CUDA tests beside the training of the fit's models (the tests are short and small).
  (
    ctest --test-dir "$BUILD" -L cuda --output-on-failure -j 1 > "$s/gpu_ctest.log" 2>&1
    echo "rc=$?" >> "$s/gpu_ctest.log"
  ) &
  (
    bench/device/fit_panoptic.sh "$s/fit" --train-only > "$s/train_models.log" 2>&1
    echo "rc=$?" >> "$s/train_models.log"
  ) &
  if [ "$RANDOM_BUDGETS" = 1 ]; then
    (
      OMP_NUM_THREADS=2 bench/fit_random_budgets.sh -n 1000 -s 3 -a "$atex" -i "$s/lego.atex" -j 8 \
        -o "$s/fit_random_budgets_lego.csv" > "$s/random_budgets.log" 2>&1
      note "random budgets rc=$?"
    ) &
  fi
  if [ "$FUZZ" = 1 ]; then
    fuzz fuzz1 6 "$FUZZ_FIRST"
    note "fuzz first done (rc=$?)"
  fi
  wait
  note "step 3: timed fits"
  bench/device/fit_panoptic.sh "$s/fit" out/fitp/uniform.atex out/fitp/adaptive.atex > "$s/fit_panoptic.log" 2>&1
  note "fit_panoptic rc=$?"
  if [ "${FIT15:-0}" = 1 ]; then  # issue 21's player model (done): off unless asked for
    "$atex" fit out/fitp/stage1.atex "$s/panoptic_stage1_15MiB.atex" --budget 15MiB --data "$bb" --force --json \
      > "$s/fit15.json" 2> "$s/fit15.log"
    "$atex" eval "$s/panoptic_stage1_15MiB.atex" --data "$bb" --json > "$s/fit15.eval.json" 2>&1
  fi
  "$atex" eval out/fitp/stage1.atex --data "$bb" --json > "$s/stage1.eval.json" 2>&1
  note "step 4: stress | fuzz rest, random budgets"
  (bench/device/gpu_memory_stress.sh > "$s/gpu_memory_stress.log" 2>&1; echo "rc=$?" >> "$s/gpu_memory_stress.log") &
  if [ "$FUZZ" = 1 ]; then
    local rest
    rest=$(ls "$s/kit/build/fuzz" | grep -vxF -f <(tr , '\n' <<<"$FUZZ_FIRST") | paste -sd,)
    fuzz fuzz2 14 "$rest"
    note "fuzz rest done (rc=$?)"
  fi
  wait
  note "done"
}

snapshot() {
  set +e  # a missing log is no failure here
  {
    date +%T
    cat "$s/steps.log" 2>/dev/null
    for f in fuzz1 fuzz2; do grep "== fuzz campaign" "$s/$f.log" 2>/dev/null | tail -3; done
    tail -3 "$s/gpu_ctest.log" "$s/train_models.log" "$s/fit_panoptic.log" "$s/random_budgets.log" 2>/dev/null
    nvidia-smi --query-gpu=name,utilization.gpu,memory.used --format=csv,noheader || true
    uptime
  } > "$out/progress.txt" 2>&1
  tar czf "$out/results.tgz" --exclude='*.atex' --exclude='*.ply' --exclude='*.png' --exclude='new' \
    --exclude='artifacts' --exclude="$s/kit" --exclude="$s/corpus" "$s" out/gpu_memory_stress out/fitp/*.json out/fitp/*.log 2>/dev/null || true
  if [ -f "$s/corpus.marker" ]; then
    find "$s/corpus" -type f -newer "$s/corpus.marker" -print0 | tar czf "$out/corpus.tgz" --null -T - 2>/dev/null || true
    find "$s" -path '*artifacts*' -type f -print0 | tar czf "$out/artifacts.tgz" --null -T - 2>/dev/null || true
  fi
  [ -f "$s/panoptic_stage1_15MiB.atex" ] && cp "$s/panoptic_stage1_15MiB.atex" "$out/" || true
}

case $phase in
  start)
    steps_running "$s" || {
      prepare
      export RUNS FUZZ_SECONDS FUZZ_FIRST FUZZ RANDOM_BUDGETS
      start_steps "$s" 's=out/s23'
    }
    ;&
  wait) follow_until "$start" "$out" steps_finished "$s" ;;
  *) echo "unknown phase $phase (start | wait)" >&2; exit 2 ;;
esac
