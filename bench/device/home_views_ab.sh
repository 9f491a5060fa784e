#!/usr/bin/env bash
# Issue 25: the home-rank view split (each device keeps only its share of the target images)
# against the commit before it, in one device call on four GPUs: multi_gpu.sh's scaling runs
# (batch 4 per GPU, MULTI_GPU_FINE fine steps, hull + volume init, 1, 2 and 4 GPUs, peak memory
# per GPU) of the new tree, then of .oldsrc (`git archive OLD | tar -x -C .oldsrc`), after the
# CUDA parity test and the schedule tests of the new tree.
#   bench/device/home_views_ab.sh OUT      (OUT/ab.tgz: each side's multi_gpu.json, peaks and logs;
#                                           a device call returns only a few dozen files)
source "$(dirname "$0")/common.sh"
dest=$1
out=out/home_views_ab
mkdir -p "$dest" "$out"
export NCCL_NVLS_ENABLE=0 MULTI_GPU_FINE=${MULTI_GPU_FINE:-1000}
jobs=$(( $(nproc) / 2 ))
BUILD_TREE_OPTIONS="-DATEX_NCCL=ON -DATEX_TESTS=ON -DATEX_BENCHMARKS=OFF" \
  build_tree . bg-nccl "$jobs" atex_cli nccl_data_parallel_test backend_parity_test train_test \
  > "$out/build_new.log" 2>&1 &
new_build=$!
BUILD_TREE_OPTIONS="-DATEX_NCCL=ON -DATEX_TESTS=OFF -DATEX_BENCHMARKS=OFF" \
  build_tree .oldsrc build-old "$jobs" atex_cli > "$out/build_old.log" 2>&1 &
old_build=$!
wait "$new_build" || { tail -20 "$out/build_new.log"; exit 1; }
wait "$old_build" || { tail -20 "$out/build_old.log"; exit 1; }
for t in backend_parity_test train_test; do
  rc=0
  "$(find bg-nccl -name "$t" -type f -perm -u+x | head -1)" > "$out/test_$t.log" 2>&1 || rc=$?
  echo "$t rc=$rc"
done
export ATEX_SKIP_BUILD=1
for side in new old; do
  build=bg-nccl
  [ "$side" = old ] && build=build-old
  ATEX_GPU_BUILD=$build MULTI_GPU_PHASE=scale MULTI_GPU_ARGS="--set stage1.init_method=auto" \
    bench/device/multi_gpu.sh "$out/$side" > "$out/$side.log" 2>&1 || echo "$side failed"
  rm -f "$out/$side"/*.atex
  grep -E '"(views_per_s|peak_per_gpu|step_rate)' "$out/$side/multi_gpu.json" || true
done
tar czf "$dest/ab.tgz" -C "$out" .
