#!/usr/bin/env bash
# Build with CUDA and run the GPU test suite (parity of every kernel with the CPU
# reference). For a machine with an NVIDIA GPU; the normal test command
# (./atex.sh test) runs the same tests but they skip without a device.
#   bench/gpu_check.sh [BUILD_DIR] [JOBS]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build-gpu}
JOBS=${2:-$(nproc)}
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DATEX_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=${ATEX_CUDA_ARCH:-90} \
  ${ATEX_DATA_DIR:+-DATEX_DATA_DIR=$ATEX_DATA_DIR} >/dev/null
cmake --build "$BUILD" -j "$JOBS"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
ctest --test-dir "$BUILD" -L cuda --output-on-failure -j 1
