#!/usr/bin/env bash
# Issue 25's targets on one machine of four GPUs, at the default Panoptic schedule, in two or
# three device calls (a lent machine allows 10 minutes per command; the steps run in the
# background under setsid and outlive a call while the machine stays warm, so each next `wait`
# call must follow at once):
#   bench/device/multi_gpu_session.sh start OUT   build (NCCL on), then start the steps
#   bench/device/multi_gpu_session.sh wait OUT    follow them until they end or CALL_SECONDS pass
# Steps (logs and rows in out/mgs/, a copy in OUT/results.tgz, OUT/progress.txt):
#   1. nccl_data_parallel_test; the scaling runs of multi_gpu.sh (batch 4 per GPU, 300 fine steps,
#      1, 2 and 4 GPUs, hull + volume init); the same 2- and 4-GPU runs with --profile, for the
#      all-reduce's share of a step (what overlapping it with the backward could save at most)
#   2. quality at the defaults (stage 1, batch 4 in total), two seeds on 1 GPU and on 2 GPUs, each
#      evaluated; the seed-6666 runs checkpoint at fine step 7,000 of 14,000. Round one runs
#      1 GPU seed 6666 (GPU 0), 1 GPU seed 1 (GPU 1) and 2 GPUs seed 6666 (GPUs 2,3) at once;
#      round two 2 GPUs seed 1 (GPUs 0,1) beside the resumes on GPUs 2,3: the 2-GPU checkpoint
#      resumed on 1 GPU, then the 1-GPU checkpoint resumed on 2 GPUs. Each process gets a quarter
#      of the cores (OMP_NUM_THREADS), so that concurrent runs do not slow one another's stereo
#      initialisation; the wall times compare runs made the same way.
#   3. multi_gpu.sh's memory phase (1 GPU against 2 GPUs at NCCL's defaults and with 4 CTAs, the
#      Simple protocol and 1 MiB buffers), alone on the machine
#   4. with .oldsrc (an earlier commit, see common.sh's build_old): issue 23's timed fits,
#      fit_panoptic.sh (its own short models, then the old and the new CLI), alone on the machine
#   5. multi_gpu_summary.py: out/mgs/summary.json
# With .fuzzkit/kit.tar.xz (bench/device/fuzz_kit.sh pack build-fuzz fuzz_gltf,fuzz_pth) and
# .fuzzcorpus (their corpora), issue 24's fuzz campaign of those two targets runs niced on half
# the cores during step 2 (it ends before step 4); OUT/corpus.tgz holds the corpus's new inputs.
# MGS_TESTS: more test executables (CMake targets) to build and run first, e.g. the CUDA parity
# test of a change the steps measure. MGS_SEEDS: the two seeds of step 2 (default "6666 1"; the
# first is checkpointed and resumed);
# MGS_STEPS: which of the steps 1 to 4 run (default "1 2 3 4"); MGS_PROFILE=0 leaves out step 1's
# profiled runs. Step 1's scaling rows carry each run's peak memory per GPU (scale/multi_gpu.json).
# The steps run the scripts of the source tree: leave bench/device unchanged between the calls.
source "$(dirname "$0")/common.sh"
phase=$1 out=$2
s=out/mgs
mkdir -p "$out" "$s"
start=$(date +%s)
CALL_SECONDS=${CALL_SECONDS:-540}
export ATEX_GPU_BUILD=bg-nccl
BUILD=bg-nccl
atex=$BUILD/bin/atex

prepare() {
  [ -d out/devdata ] || cp -r .devdata out/devdata  # runs in flight read it
  if [ -f .fuzzkit/kit.tar.xz ] && [ -d .fuzzcorpus ] && [ ! -d "$s/kit" ]; then
    mkdir -p "$s/kit"
    tar -C "$s/kit" -xJf .fuzzkit/kit.tar.xz
    cp -r .fuzzcorpus "$s/corpus"
    touch "$s/corpus.marker"
  fi
  [ -d .oldsrc ] && { build_old 16 > "$s/build_old.log" 2>&1 || echo "build-old failed" >> "$s/steps.log"; } &
  BUILD_TREE_OPTIONS="-DATEX_NCCL=ON -DATEX_TESTS=ON -DATEX_BENCHMARKS=OFF" \
    build_tree . "$BUILD" "$(nproc)" atex_cli nccl_data_parallel_test ${MGS_TESTS:-} > "$s/build.log" 2>&1 ||
    { echo "build failed" >> "$s/steps.log"; tail -20 "$s/build.log"; exit 1; }
  wait
}

steps() {
  set +e
  local t0
  t0=$(date +%s)
  note() { echo "$(date +%T) [$(( $(date +%s) - t0 ))s] $*" >> "$s/steps.log"; }
  note "orchestrator started"
  export ATEX_SKIP_BUILD=1 ATEX_DEVDATA=out/devdata NCCL_NVLS_ENABLE=0
  bb=out/devdata/panoptic_basketball
  local threads=$(( $(nproc) / 4 ))
  # train NAME ARGS...: NAME.train.json, NAME.log, NAME.wall, then NAME.eval.json, evaluated on
  # the run's first GPU (not on GPU 0, which another run may be training on). A run that
  # finished and was evaluated is not run again, one that trained but was not evaluated is only
  # evaluated, and one still in flight (started by an earlier `start`, whose orchestrator was
  # stopped) is waited for: `start` again after a failed run or a fix redoes only what is missing.
  train() {
    local name=$1
    shift
    local t gpu=0 previous=
    for arg in "$@"; do
      [ "$previous" = --gpus ] && gpu=${arg%%,*}
      previous=$arg
    done
    evaluate() {
      CUDA_VISIBLE_DEVICES=$gpu OMP_NUM_THREADS=$threads "$atex" eval "$s/$name.atex" --data "$bb" --json \
        > "$s/$name.eval.json" 2> "$s/$name.eval.log"
      note "$name done"
    }
    if grep -q '"psnr"' "$s/$name.eval.json" 2>/dev/null; then return 0; fi
    if [ -f "$s/$name.log" ] && ! grep -q '^rc=' "$s/$name.log"; then
      while ! grep -q '^rc=' "$s/$name.log"; do sleep 5; done  # in flight: its own wrapper evaluates it
      for _ in $(seq 60); do
        grep -q '"psnr"' "$s/$name.eval.json" 2>/dev/null && return 0
        sleep 5
      done
    fi
    if grep -q '^rc=0$' "$s/$name.log" 2>/dev/null && [ -f "$s/$name.atex" ]; then  # trained, not evaluated
      evaluate
      return 0
    fi
    t=$(date +%s.%N)
    OMP_NUM_THREADS=$threads "$atex" train --data "$bb" --stage 1 --force --json --out "$s/$name.atex" "$@" \
      > "$s/$name.train.json" 2> "$s/$name.log"
    echo "rc=$?" >> "$s/$name.log"
    python3 -c "import time; print(time.time() - $t)" > "$s/$name.wall"
    evaluate
  }
  nvidia-smi --query-gpu=index,name,driver_version --format=csv,noheader > "$s/gpu.txt"
  nvidia-smi topo -m > "$s/topology.txt" 2>&1
  local seeds=(${MGS_SEEDS:-6666 1}) wanted=" ${MGS_STEPS:-1 2 3 4} "
  local a=${seeds[0]} b=${seeds[1]}
  local t
  for t in ${MGS_TESTS:-}; do  # before the timed steps, alone on the machine
    "$(find "$BUILD" -name "$t" -type f -perm -u+x | head -1)" > "$s/test_$t.log" 2>&1
    note "$t rc=$?"
  done
  [[ $wanted == *" 1 "* ]] && note "step 1: gradient test, scaling, profile"
  if [[ $wanted == *" 1 "* ]] && ! grep -q '"scale_4gpu"' "$s/scale/multi_gpu.json" 2>/dev/null; then
    "$(find "$BUILD" -name nccl_data_parallel_test -type f -perm -u+x | head -1)" > "$s/nccl_test.log" 2>&1
    note "nccl_data_parallel_test rc=$?"
    MULTI_GPU_PHASE=scale MULTI_GPU_ARGS="--set stage1.init_method=auto" bench/device/multi_gpu.sh "$s/scale" \
      > "$s/scale.log" 2>&1
    note "scale rc=$?"
  fi
  local short=(--data "$bb" --stage 1 --force --json --profile --set stage1.init_method=auto
               --set stage1.coarse_iterations=200 --set stage1.fine_iterations=300 --set eval_every=0)
  local gpus
  for gpus in 0,1 0,1,2,3; do
    [[ $wanted == *" 1 "* ]] && [ "${MGS_PROFILE:-1}" != 0 ] || break
    local n=$(( ${#gpus} / 2 + 1 ))
    grep -q '"all_reduce_ms"' "$s/profile_${n}gpu.train.json" 2>/dev/null && continue
    "$atex" train "${short[@]}" --gpus $gpus --set stage1.batch_size=$(( 4 * n )) --out "$s/profile_${n}gpu.atex" \
      > "$s/profile_${n}gpu.train.json" 2> "$s/profile_${n}gpu.log"
  done
  # Issue 24's fuzzing of the two targets short of depth, niced, on half the cores while the GPUs train.
  local fuzz_pid=
  if [ -d "$s/kit" ] && ! grep -q "fuzz rc=" "$s/steps.log" && ! pgrep -f "[f]uzz_campaign.sh" > /dev/null; then
    (
      LD_LIBRARY_PATH=$PWD/$s/kit/lib nice -n 19 bench/fuzz_campaign.sh --prebuilt --build "$s/kit/build" \
        --corpus "$s/corpus" --jobs "${FUZZ_JOBS:-32}" --seconds "${FUZZ_SECONDS:-300}" \
        --runs "${FUZZ_RUNS:-7000000}" --targets fuzz_gltf,fuzz_pth --out "$s/fuzz" > "$s/fuzz.log" 2>&1
      note "fuzz rc=$?"
    ) &
    fuzz_pid=$!
  fi
  local half=(--checkpoint-every 7000) pids=()
  if [[ $wanted == *" 2 "* ]]; then
    note "step 2: quality round one"
    train "q1_s$a" --gpus 0 --set seed="$a" --checkpoint-dir "$s/ckpt_q1_s$a" "${half[@]}" & pids+=($!)
    train "q1_s$b" --gpus 1 --set seed="$b" & pids+=($!)
    train "q2_s$a" --gpus 2,3 --set seed="$a" --checkpoint-dir "$s/ckpt_q2_s$a" "${half[@]}" & pids+=($!)
    wait "${pids[@]}"
    note "quality round two"
    pids=()
    train "q2_s$b" --gpus 0,1 --set seed="$b" & pids+=($!)
    (
      train resume_2to1 --gpus 2 --resume "$s/ckpt_q2_s$a"
      train resume_1to2 --gpus 2,3 --resume "$s/ckpt_q1_s$a"
    ) & pids+=($!)
    wait "${pids[@]}"
  fi
  if [[ $wanted == *" 3 "* ]]; then
    note "step 3: memory"
    MULTI_GPU_MEMORY_VARIANTS=default,ctas_4_simple_1mib \
      MULTI_GPU_PHASE=memory MULTI_GPU_ARGS="--set stage1.init_method=auto" bench/device/multi_gpu.sh "$s/memory" \
      > "$s/memory.log" 2>&1
    note "memory rc=$?"
  fi
  # Issue 23's timed fits: fit_panoptic.sh trains its own short models (without fast-object
  # Gaussians, which the old CLI cannot read; the 1-GPU runs above have them), then fits them
  # with the old and the new CLI, alone on the machine once the fuzzing is over.
  if [[ $wanted == *" 4 "* ]] && [ -x build-old/bin/atex ] && [ ! -s "$s/fit/fit_panoptic.jsonl" ]; then
    note "step 4: timed fits"
    [ -n "$fuzz_pid" ] && wait "$fuzz_pid"
    rm -rf out/fitp  # models of another script or an earlier attempt: not reused
    bench/device/fit_panoptic.sh "$s/fit" > "$s/fit_panoptic.log" 2>&1
    note "fit_panoptic rc=$?"
  fi
  [ -n "$fuzz_pid" ] && wait "$fuzz_pid"
  python3 bench/device/multi_gpu_summary.py "$s" > "$s/summary.json" 2> "$s/summary.log"
  note "done"
}

snapshot() {
  set +e
  {
    date +%T
    cat "$s/steps.log" 2>/dev/null
    nvidia-smi --query-gpu=index,utilization.gpu,memory.used --format=csv,noheader
    uptime
    cat "$s/summary.json" 2>/dev/null
  } > "$out/progress.txt" 2>&1
  tar czf "$out/results.tgz" --exclude='*.atex' --exclude='ckpt_*' --exclude="$s/kit" --exclude="$s/corpus" \
    --exclude='artifacts' "$s" out/fitp/*.json out/fitp/*.log 2>/dev/null
  if [ -f "$s/corpus.marker" ]; then
    find "$s/corpus" -type f -newer "$s/corpus.marker" -print0 | tar czf "$out/corpus.tgz" --null -T - 2>/dev/null
  fi
}

case $phase in
  start)
    # MGS_RESTART=1: stop a running orchestrator first (its runs in flight go on and are waited for).
    if [ -n "${MGS_RESTART:-}" ] && [ -f "$s/steps.pid" ]; then
      kill "$(cat "$s/steps.pid")" 2>/dev/null || true
      sleep 1
    fi
    steps_running "$s" || {
      prepare
      export s
      start_steps "$s" 'BUILD=bg-nccl; atex=$BUILD/bin/atex'
    }
    ;&
  wait) follow_until "$start" "$out" steps_finished "$s" ;;
  *) echo "unknown phase $phase (start | wait)" >&2; exit 2 ;;
esac
