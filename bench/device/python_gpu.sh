#!/usr/bin/env bash
# The Python module on a GPU machine (Ubuntu 24.04, PyTorch's Python at /opt/torch/.venv):
# builds atex._atex with CUDA for that interpreter, runs the Python tests there (the GPU ones
# included: CUDA renders, torch.from_dlpack without a copy), and measures the Python overhead
# on a CUDA render of a Panoptic model at 1352x1014 against `atex fps` (target <= 5 %).
#   bench/device/python_gpu.sh OUT_DIR         -> OUT_DIR/{gpu.txt,pytest.log,overhead.json}
#   bench/device/python_gpu.sh OUT_DIR build   only configure and build (e.g. in the background of
#                                              another job, so that a later call only tests)
# PY_GPU_MODEL: a Panoptic .atex to time (default: a short stage-1 model trained here, 6,000 fine steps).
# PYTHON: the interpreter (default /opt/torch/.venv/bin/python3, else python3).
#
# pybind11 is header-only. The script takes, in order: Debian/Ubuntu's pybind11-dev (its CMake
# package), the interpreter's `pybind11` pip package, or the pybind11 headers PyTorch wheels ship
# in torch/include (passed as ATEX_PYBIND11_INCLUDE_DIR), so nothing has to be carried.
source "$(dirname "$0")/common.sh"
out=${1:?usage: bench/device/python_gpu.sh OUT_DIR}
mkdir -p "$out"
PY=${PYTHON:-/opt/torch/.venv/bin/python3}
[ -x "$PY" ] || PY=$(command -v python3)
PYBUILD=${ATEX_GPU_PY_BUILD:-bg-python}
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$out/gpu.txt"
"$PY" -c 'import sys, sysconfig, os; inc = sysconfig.get_paths()["include"]; print(sys.version.split()[0], inc, os.path.exists(os.path.join(inc, "Python.h")))' \
  | tee "$out/python.txt"
grep -q True "$out/python.txt" || { echo "python_gpu.sh: no Python.h for $PY (apt install python3-dev)" | tee -a "$out/python.txt"; exit 1; }

pybind11_args=()
if [ -f /usr/share/cmake/pybind11/pybind11Config.cmake ] || [ -f /usr/lib/cmake/pybind11/pybind11Config.cmake ]; then
  echo "pybind11: the system's CMake package" | tee -a "$out/python.txt"
elif dir=$("$PY" -c 'import pybind11; print(pybind11.get_cmake_dir())' 2>/dev/null); then
  pybind11_args=(-Dpybind11_DIR="$dir")
  echo "pybind11: pip package ($dir)" | tee -a "$out/python.txt"
else
  inc=$("$PY" -c 'import os, torch; print(os.path.join(os.path.dirname(torch.__file__), "include"))')
  [ -f "$inc/pybind11/pybind11.h" ] || { echo "python_gpu.sh: no pybind11 anywhere" | tee -a "$out/python.txt"; exit 1; }
  pybind11_args=(-DATEX_PYBIND11_INCLUDE_DIR="$inc")
  echo "pybind11: headers shipped with torch ($inc)" | tee -a "$out/python.txt"
fi

cmake -S . -B "$PYBUILD" -DCMAKE_BUILD_TYPE=Release -DATEX_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=90 -DATEX_PYTHON=ON \
  -DPython3_EXECUTABLE="$PY" -DATEX_BENCHMARKS=OFF "${pybind11_args[@]}" > "$out/configure.log"
cmake --build "$PYBUILD" -j "$(nproc)" --target atex_python atex_cli 2>&1 | tail -2
[ "${2:-}" = build ] && exit 0

export PYTHONPATH=$PWD/$PYBUILD/python ATEX_DATA_DIR=$PWD/.devdata ATEX_SOURCE_DIR=$PWD ATEX_BINARY_DIR=$PWD/$PYBUILD
export ATEX_REQUIRE_GPU=1
# PyTorch's venv may lack pytest (or numpy): borrow the system's pure-Python packages, after the venv's.
if ! "$PY" -c 'import pytest, numpy' 2>/dev/null; then
  export PYTHONPATH=$PYTHONPATH:/usr/lib/python3/dist-packages
  echo "python_gpu.sh: pytest/numpy from /usr/lib/python3/dist-packages" | tee -a "$out/python.txt"
fi
"$PY" -c 'import numpy, pytest, torch; print("numpy", numpy.__version__, "pytest", pytest.__version__, "torch", torch.__version__)' \
  | tee -a "$out/python.txt"
"$PY" -m pytest -q -p no:cacheprovider python/tests -rs > "$out/pytest.log" 2>&1 || echo "python_gpu.sh: pytest failed (see pytest.log)"
tail -15 "$out/pytest.log"

model=${PY_GPU_MODEL:-}
if [ -z "$model" ]; then
  atex=$PYBUILD/bin/atex train_short_stage1 out/pygpu 0
  model=out/pygpu/stage1.atex
fi
"$PY" bench/python_overhead.py --atex "$PYBUILD/bin/atex" --asset "$model" --data "$bb" --size 1352x1014 \
  --repeats 200 | tee "$out/overhead.json"
