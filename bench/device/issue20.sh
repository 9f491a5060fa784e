#!/usr/bin/env bash
# Issue 20 GPU calls on a machine of one or more GPUs (nvidia-h100-x2 in the issue's runs):
#   bench/device/issue20.sh start  OUT JOB   build the CLI and the four parity tests, start JOB of
#                                            parallel_session.sh (base | base2 | stereo) in the background,
#                                            run the parity tests beside it on the last GPU (PARITY_TESTS=0:
#                                            neither), follow the job
#   bench/device/issue20.sh wait   OUT JOB   follow the job until it ends or the call's time is up
#   bench/device/issue20.sh sheets OUT JOB   contact-sheet frames (test cameras 0 and 10, every 3rd
#                                            frame) of every stage-1 model of the job
#                                            (SHEET_VARIANTS="a b": of those variants only), and the FPS at
#                                            1352x1014 of every model of the job, in OUT/frames.tgz
#                                            (NEAR_PLANES="0.5 1 2": also evaluations at those near planes)
# Each call's OUT gets results.tgz and progress.txt (parallel_session.sh); `start` also parity.log.
source "$(dirname "$0")/common.sh"
phase=$1 out=$2 job=${3:-base}
mkdir -p "$out"
export CALL_SECONDS=${CALL_SECONDS:-500} JOBS=$job PARITY=0
case $phase in
  start)
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$out/gpu.txt"
    if [ "${PARITY_TESTS:-1}" = 1 ]; then  # PARITY_TESTS=0: the CLI only (the tests passed on this CUDA code)
      build_tree . "$BUILD" "$(nproc)" atex_cli backend_parity_test deform_parity_test render_parity_test \
        loss_parity_test 2>&1 | tail -2
      last=$(nvidia-smi --query-gpu=index --format=csv,noheader | tail -1)
      (CUDA_VISIBLE_DEVICES=$last ctest --test-dir "$BUILD" -R parity --output-on-failure -V \
         > "$out/parity.log" 2>&1; grep -E "tests passed|tests failed|camera colours|Failed|FAILED" "$out/parity.log" \
         > "$out/parity_summary.txt") &
    fi
    bench/device/parallel_session.sh start "$out"
    wait
    cat "$out/parity_summary.txt" 2>/dev/null || true
    ;;
  wait)
    bench/device/parallel_session.sh wait "$out"
    ;;
  sheets)
    for variant in ${SHEET_VARIANTS:-*}; do for model in out/"$job"/models/basketball/$variant/s*/stage1.atex; do
      dir=$(dirname "$model")
      name=$(echo "$dir" | awk -F/ '{print $(NF-1) "_" $NF}')
      "$atex" eval "$model" --data "$bb" --json > "$dir/stage1.eval.json"
      bench/device/contact_frames.sh "$model" "$dir/stage1.eval.json" "out/frames/$name"
      cp "$dir/stage1.eval.json" "out/frames/$name/"
      for near in ${NEAR_PLANES:-}; do
        "$atex" eval "$model" --data "$bb" --near-plane $near --json > "out/frames/$name/near$near.eval.json"
      done
    done; done
    # Render speed of every full-size model of the job at the paper's 1352x1014 (run_matrix ran with
    # --skip-fps while two jobs shared the GPUs).
    for model in out/"$job"/models/basketball/*/s*/*.atex; do
      dir=$(dirname "$model")
      name=$(echo "$dir" | awk -F/ '{print $(NF-1) "_" $NF}')_$(basename "$model" .atex)
      "$atex" fps "$model" --data "$bb" --view test:0 --size 1352x1014 --repeats 100 --json \
        > "out/frames/$name.fps.json" || true
    done
    tar czf "$out/frames.tgz" -C out frames
    ;;
  *) echo "unknown phase $phase" >&2; exit 2 ;;
esac
