#!/usr/bin/env bash
# GPU memory stress (issue 24, item 5): work that does not fit on the card is refused cleanly
# (exit 1, "E11 limit-exceeded: out of GPU memory ... MiB asked; ... GiB free of ... GiB"), or
# runs; never a crash, a hang or "E18 internal". Each cell's outcome goes into
# out/gpu_memory_stress/table.md (and .json):
#   unit        kernels' memory_limit_test: a buffer of twice the card, then a small one
#   render_big  8M Gaussians as large as the screen (tens of billions of tile intersections)
#               rendered at 1352x1014 (atex render, atex fps): expected E11
#   train_big   stage 1 on Panoptic from 6M initial points, batch 64 (all 27 training
#               cameras twice): E11 or trained
#   train_fit   the same with a batch of 4: expected to train (the documented fallback:
#               a smaller stage1.batch_size / stage1.densify.max_gaussians)
# Run from the repository root on the GPU machine:
#   bench/device/gpu_memory_stress.sh            (builds bg/ with CUDA when bg/bin/atex is missing)
source "$(dirname "$0")/common.sh"
out=out/gpu_memory_stress
mkdir -p "$out"
build_tree . "$BUILD" "$(nproc)" atex_cli memory_limit_test > "$out/build.log" 2>&1  # incremental when bg/ exists
rows=()
cell() {  # NAME EXPECT(limit|ok|either) COMMAND...
  local name=$1 expect=$2
  shift 2
  local start status outcome message
  start=$(date +%s)
  set +e
  timeout "${CELL_SECONDS:-1800}" "$@" > "$out/$name.out" 2> "$out/$name.err"
  status=$?
  set -e
  # (|| true: no error line is no failure, under pipefail)
  message=$(grep -E "E[0-9]+ |error|Error" "$out/$name.err" | tail -1 | cut -c1-240 | tr '|' '/' || true)
  if [ $status -eq 124 ]; then
    outcome="FAIL: hang (${CELL_SECONDS:-1800} s)"
  elif [ $status -ge 128 ] || grep -q "E18 internal\|terminate called\|Segmentation\|core dumped" "$out/$name.err"; then
    outcome="FAIL: crash or internal error (exit $status)"
  elif [ $status -eq 0 ]; then
    [ "$expect" = limit ] && outcome="ran (fit on this card)" || outcome="ok"
  elif grep -q "E11 limit-exceeded" "$out/$name.err"; then
    if grep -q "asked" "$out/$name.err" && grep -q "free of" "$out/$name.err"; then
      outcome="refused cleanly (E11, sizes named)"
    else
      outcome="refused (E11) without the sizes"
    fi
    [ "$expect" = ok ] && outcome="$outcome; expected to fit"
  else
    outcome="FAIL: other error (exit $status)"
  fi
  rows+=("$name|$expect|$status|$(( $(date +%s) - start ))|$outcome|$message")
  echo "== $name: $outcome (exit $status) $message"
}

test_bin=$(find "$BUILD" -name memory_limit_test -type f -perm -u+x | head -1)
cell unit ok "$test_bin"

# 8M Gaussians of scale e^0 = 1 m, fully opaque, spread over 1 m: each covers the whole screen.
# Positions and colours are random per Gaussian: a file of repeated blocks compresses ~7,000:1
# and the reader refuses it as a decompression bomb (E11 before any GPU work).
python3 - "$out/big.ply" <<'PY'
import struct, sys, random
n = 8_000_000
props = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
         "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
with open(sys.argv[1], "wb") as f:
    f.write(("ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % n).encode())
    for p in props:
        f.write(("property float %s\n" % p).encode())
    f.write(b"end_header\n")
    try:
        import numpy as np
        rng = np.random.default_rng(24)
        rows = np.zeros((n, 17), dtype="<f4")
        rows[:, 0:3] = rng.uniform(-.5, .5, (n, 3))
        rows[:, 6:9] = rng.uniform(0, 1, (n, 3))
        rows[:, 9] = 5.0
        rows[:, 13] = 1.0
        f.write(rows.tobytes())
    except ImportError:
        rng = random.Random(24)
        for _ in range(n):
            u = rng.random
            f.write(struct.pack("<17f", u() - .5, u() - .5, u() - .5, 0, 0, 0, u(), u(), u(), 5.0,
                                0.0, 0.0, 0.0, 1, 0, 0, 0))
PY
"$atex" convert "$out/big.ply" "$out/big.atex" --force > /dev/null 2> "$out/convert.err" || cat "$out/convert.err"
cell render_big limit "$atex" render "$out/big.atex" -o "$out/big.png" --force --backend cuda --data "$bb" --view test:0
cell fps_big limit "$atex" fps "$out/big.atex" --data "$bb" --size 1352x1014 --backend cuda --repeats 3
# A few steps reach the peak memory of a step (4.3 M Gaussians at batch 64 run 0.3-0.4 steps/s).
short=(--set stage1.coarse_iterations=10 --set stage1.fine_iterations=10 --set eval_every=0 --set checkpoint_every=0)
cell train_big either "$atex" train --data "$bb" --stage 1 --backend cuda --force --out "$out/train_big.atex" \
  "${short[@]}" --set stage1.init_points=6000000 --set stage1.densify.max_gaussians=20000000 --set stage1.batch_size=64
cell train_fit ok "$atex" train --data "$bb" --stage 1 --backend cuda --force --out "$out/train_fit.atex" \
  "${short[@]}" --set stage1.init_points=1000000 --set stage1.batch_size=4
rm -f "$out/big.ply"

{
  echo "| cell | expected | exit | seconds | outcome | message |"
  echo "|---|---|---:|---:|---|---|"
  for row in "${rows[@]}"; do echo "| ${row//|/ | } |"; done
  echo
  echo "GPU: $(nvidia-smi --query-gpu=name,memory.total --format=csv,noheader | head -1); $(date -u +%Y-%m-%d); bench/device/gpu_memory_stress.sh"
} > "$out/table.md"
cat "$out/table.md"
if printf '%s\n' "${rows[@]}" | grep -q "FAIL"; then exit 1; fi
