#!/usr/bin/env bash
# The multi-view stereo of the "mvs" initialisation on the GPU machine's CPU cores (it runs
# without CUDA): time, fused points and coverage of Panoptic basketball's first timestep
# (bench/bench_mvs.cc), at the default 320-pixel stereo resolution and at 640 (the images'
# own size), with every core and with 8.
#   bench/device/mvs_bench.sh OUT_DIR   -> OUT_DIR/bench_mvs_*.json, summary on stdout
source "$(dirname "$0")/common.sh"
out=$1
mkdir -p "$out"
BUILD_TREE_OPTIONS="-DATEX_BENCHMARKS=ON" build_tree . "$BUILD" 16 bench_mvs
nproc
for side in 320 640; do
  for threads in $(nproc) 8; do
    OMP_NUM_THREADS=$threads MVS_SIDE=$side ATEX_DATA_DIR=.devdata "$BUILD/bench/bench_mvs" \
      --benchmark_format=json > "$out/bench_mvs_${side}_t$threads.json"
    python3 -c "import json,sys; b=json.load(open(sys.argv[1]))['benchmarks'][0]; \
print(sys.argv[1], round(b['real_time'],1), 's', {k: round(v,3) for k,v in b.items() if k.startswith(('cov','fused','points','reproj','planes'))})" \
      "$out/bench_mvs_${side}_t$threads.json"
  done
done
