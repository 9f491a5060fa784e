#!/usr/bin/env bash
# Data-parallel training on two GPUs (issue 25), Panoptic basketball stage 1, about 8 minutes
# on 2×H100:
#   (a) scaling: steps/s of the fine phase with the batch per GPU fixed (4 views): 1 GPU with
#       batch 4 against 2 GPUs with batch 8;
#   (b) quality: the same TOTAL views per step (batch 4) on 1 GPU and on 2 GPUs (2 each), both
#       evaluated (atex eval --json), wall time and peak memory per GPU (nvidia-smi, sampled);
#   (c) resume: the 2-GPU run's checkpoint at fine step 750 resumed on 1 GPU, evaluated;
# after the two-GPU gradient test (nccl_data_parallel_test).
#
#   bench/device/multi_gpu.sh OUT_DIR [FINE_STEPS=1500]
# MULTI_GPU_PHASE: all (default), build (the build only), scale (the gradient test and (a) only),
# memory ((a) on 1 and 2 GPUs under NCCL settings that shrink its buffers: which of them brings the
# 2-GPU peak per GPU down to one GPU's, and what each costs in steps/s; OUT_DIR/memory.json).
# ATEX_GPU_BUILD picks the build folder (common.sh): a NCCL build beside another job's uses its own.
# MULTI_GPU_ARGS adds train options to every run (e.g. "--set stage1.init_method=auto" to skip the
# stereo's seconds); the 2-GPU quality run writes its checkpoint at half of FINE_STEPS.
#
# Results: OUT_DIR/multi_gpu.json (a summary) beside every run's report, log and evaluation.
source "$(dirname "$0")/common.sh"
out=$1
fine=${2:-1500}
# NVLink multicast stays off on the lent machines (KINDS.md): atex's ranks inherit this environment.
export NCCL_NVLS_ENABLE=0
mkdir -p "$out"
BUILD_TREE_OPTIONS="-DATEX_NCCL=ON -DATEX_TESTS=ON -DATEX_BENCHMARKS=OFF" \
  build_tree . "$BUILD" "$(nproc)" atex_cli nccl_data_parallel_test > "$out/build.log" 2>&1 ||
  { tail -20 "$out/build.log"; exit 1; }
phase=${MULTI_GPU_PHASE:-all}
[ "$phase" = build ] && exit 0
nvidia-smi --query-gpu=index,name,driver_version --format=csv,noheader | tee "$out/gpu.txt"
# The GPUs' link (NVLink or PCIe) decides what the per-step all-reduce costs.
nvidia-smi topo -m > "$out/topology.txt" 2>&1 || true
head -6 "$out/topology.txt"
ngpus=$(nvidia-smi --query-gpu=index --format=csv,noheader | wc -l)
# First the two-GPU gradient test (kernels/tests/nccl_data_parallel_test.cc): seconds.
nccl_test=$(find "$BUILD" -name nccl_data_parallel_test -type f -perm -u+x | head -1)
if [ -n "$nccl_test" ]; then  # an A/B run of an older build may come without it
  "$nccl_test" 2>&1 | tee "$out/nccl_test.log" | tail -3
fi
# shellcheck disable=SC2206  # MULTI_GPU_ARGS is words
extra=(${MULTI_GPU_ARGS:-})
# Fine steps of the scaling and memory runs: 300, or MULTI_GPU_FINE (enough steps for every image
# to be drawn, e.g. 1000, make the peaks comparable: a device keeps the images it has drawn).
scale_fine=${MULTI_GPU_FINE:-300}
common=(--data "$bb" --stage 1 --force --json --set stage1.coarse_iterations=200 --set eval_every=0
        --set checkpoint_every=0 "${extra[@]}")

# Runs `atex train` with ARGS... as run NAME while sampling the GPUs' memory every 200 ms;
# writes NAME.train.json, NAME.log, NAME.memory.csv, NAME.peak.json (the largest sample of each
# GPU, MiB) and NAME.wall (seconds).
run() {  # NAME ARGS...
  local name=$1
  shift
  nvidia-smi --query-gpu=index,memory.used --format=csv,noheader,nounits -lms 200 > "$out/$name.memory.csv" &
  local sampler=$!
  local start end
  start=$(date +%s.%N)
  "$atex" train "${common[@]}" "$@" > "$out/$name.train.json" 2> "$out/$name.log" || {
    kill "$sampler"
    echo "run $name failed:"
    tail -20 "$out/$name.log"
    return 1
  }
  end=$(date +%s.%N)
  kill "$sampler"
  python3 -c "print($end - $start)" > "$out/$name.wall"
  python3 - "$out/$name.memory.csv" > "$out/$name.peak.json" <<'PY'
import json, sys
peak = {}
for line in open(sys.argv[1]):
    parts = [p.strip() for p in line.split(",")]
    if len(parts) == 2 and parts[1].isdigit():
        peak[int(parts[0])] = max(peak.get(int(parts[0]), 0), int(parts[1]))
print(json.dumps(peak))
PY
}

if [ "$phase" = memory ]; then
  # NCCL's per-channel, per-protocol buffers are what the 2-GPU runs added (BENCHMARKS.md, issue 25).
  variants=("default:" "buffsize_1mib:NCCL_BUFFSIZE=1048576" "channels_4:NCCL_MAX_NCHANNELS=4"
            "proto_simple:NCCL_PROTO=Simple" "ctas_4_simple_1mib:NCCL_MAX_CTAS=4 NCCL_PROTO=Simple NCCL_BUFFSIZE=1048576")
  # MULTI_GPU_MEMORY_VARIANTS (names, comma-separated) keeps only those variants.
  if [ -n "${MULTI_GPU_MEMORY_VARIANTS:-}" ]; then
    kept=()
    for v in "${variants[@]}"; do
      [[ ",$MULTI_GPU_MEMORY_VARIANTS," == *",${v%%:*},"* ]] && kept+=("$v")
    done
    [ "${#kept[@]}" -eq "$(tr , '\n' <<<"$MULTI_GPU_MEMORY_VARIANTS" | grep -c .)" ] ||
      { echo "MULTI_GPU_MEMORY_VARIANTS=$MULTI_GPU_MEMORY_VARIANTS names a variant not in: ${variants[*]%%:*}" >&2; exit 2; }
    variants=("${kept[@]}")
  fi
  run mem_1gpu --gpus 0 --out "$out/mem_1gpu.atex" --set stage1.fine_iterations="$scale_fine" --set stage1.batch_size=4
  names="mem_1gpu"
  for v in "${variants[@]}"; do
    name=mem_2gpu_${v%%:*}
    settings=${v#*:}
    (
      # shellcheck disable=SC2086,SC2163  # the settings are words (VAR=VALUE); the ranks inherit them
      [ -n "$settings" ] && export $settings
      run "$name" --gpus 0,1 --out "$out/$name.atex" --set stage1.fine_iterations="$scale_fine" --set stage1.batch_size=8
    ) || { echo "variant $name failed: left out of memory.json"; continue; }
    names="$names $name"
  done
  python3 - "$out" $names <<'PY' | tee "$out/memory.json"
import json, os, sys
out, rows = sys.argv[1], {}
for name in sys.argv[2:]:
    peak = {int(k): v for k, v in json.load(open(os.path.join(out, name + ".peak.json"))).items()}
    train = json.load(open(os.path.join(out, name + ".train.json")))
    rows[name] = {"peak_mib_per_gpu": peak,
                  "fine_steps_per_s": train["steps"]["fine"] / train["seconds"]["fine"]}
one = rows["mem_1gpu"]
for name, row in rows.items():
    row["peak_over_1gpu"] = max(row["peak_mib_per_gpu"].values()) / max(one["peak_mib_per_gpu"].values())
    row["step_rate_over_1gpu"] = row["fine_steps_per_s"] / one["fine_steps_per_s"]
print(json.dumps(rows, indent=1))
PY
  exit 0
fi

# (a) scaling: batch per GPU fixed at 4, MULTI_GPU_FINE fine steps.
run scale_1gpu --gpus 0 --out "$out/scale_1gpu.atex" --set stage1.fine_iterations="$scale_fine" --set stage1.batch_size=4
run scale_2gpu --gpus 0,1 --out "$out/scale_2gpu.atex" --set stage1.fine_iterations="$scale_fine" --set stage1.batch_size=8
# On four or more GPUs, (a) also with 4 (batch 16) and, where there are 8, with 8 (batch 32).
scales="scale_1gpu scale_2gpu"
if [ "$ngpus" -ge 4 ]; then
  run scale_4gpu --gpus 0,1,2,3 --out "$out/scale_4gpu.atex" --set stage1.fine_iterations="$scale_fine" --set stage1.batch_size=16
  scales="$scales scale_4gpu"
fi
if [ "$ngpus" -ge 8 ]; then
  run scale_8gpu --gpus 0,1,2,3,4,5,6,7 --out "$out/scale_8gpu.atex" --set stage1.fine_iterations="$scale_fine" \
    --set stage1.batch_size=32
  scales="$scales scale_8gpu"
fi
if [ "$phase" = scale ]; then
  python3 - "$out" $scales <<'PY' | tee "$out/multi_gpu.json"
import json, os, sys
out, rows = sys.argv[1], {}
for name in sys.argv[2:]:
    train = json.load(open(os.path.join(out, name + ".train.json")))
    seconds, steps = train.get("seconds", {}), train.get("steps", {})
    rows[name] = {"wall_s": float(open(os.path.join(out, name + ".wall")).read()),
                  "fine_seconds": seconds.get("fine"), "fine_steps": steps.get("fine")}
    rows[name]["fine_steps_per_s"] = rows[name]["fine_steps"] / rows[name]["fine_seconds"]
    # Peak memory per GPU (run's NAME.peak.json), the GPUs the run used only.
    peak = json.load(open(os.path.join(out, name + ".peak.json")))
    gpus = int(name.split("_")[1].rstrip("gpu"))
    rows[name]["peak_mib_per_gpu"] = {int(k): v for k, v in sorted(peak.items(), key=lambda kv: int(kv[0]))
                                      if int(k) < gpus}
# Step rate against one GPU; with the batch grown with the GPU count, views/s is that times the count.
one = rows["scale_1gpu"]["fine_steps_per_s"]
summary = {"runs": rows}
for name in sys.argv[3:]:
    gpus = int(name.split("_")[1].rstrip("gpu"))
    summary["step_rate_%dgpu_over_1gpu" % gpus] = rows[name]["fine_steps_per_s"] / one
    summary["views_per_s_%dgpu_over_1gpu" % gpus] = gpus * rows[name]["fine_steps_per_s"] / one
    peaks, one_peak = rows[name]["peak_mib_per_gpu"], rows["scale_1gpu"]["peak_mib_per_gpu"]
    if peaks and one_peak:
        summary["peak_per_gpu_%dgpu_over_1gpu" % gpus] = max(peaks.values()) / max(one_peak.values())
print(json.dumps(summary, indent=1))
PY
  exit 0
fi

# (b) quality: 4 views per step in total; the 2-GPU run writes a checkpoint half-way for (c).
run quality_1gpu --gpus 0 --out "$out/quality_1gpu.atex" --set stage1.fine_iterations="$fine" \
  --set stage1.batch_size=4
run quality_2gpu --gpus 0,1 --out "$out/quality_2gpu.atex" --set stage1.fine_iterations="$fine" \
  --set stage1.batch_size=4 --checkpoint-dir "$out/ckpt_2gpu" --checkpoint-every $((fine / 2))

# (c) the 2-GPU checkpoint resumed on one GPU.
common=(--data "$bb" --stage 1 --force --json)  # the checkpoint holds the configuration
run resume_1gpu --gpus 0 --out "$out/resume_1gpu.atex" --resume "$out/ckpt_2gpu"

for name in quality_1gpu quality_2gpu resume_1gpu; do
  "$atex" eval "$out/$name.atex" --data "$bb" --json > "$out/$name.eval.json" 2> "$out/$name.eval.log"
done

python3 - "$out" <<'PY' | tee "$out/multi_gpu.json"
import collections, json, os, sys
out = sys.argv[1]
def load(name, kind):
    path = os.path.join(out, f"{name}.{kind}.json")
    return json.load(open(path)) if os.path.exists(path) else None
def peak_mib(name):
    peak = collections.defaultdict(int)
    for line in open(os.path.join(out, f"{name}.memory.csv")):
        parts = [p.strip() for p in line.split(",")]
        if len(parts) == 2 and parts[1].isdigit():
            peak[int(parts[0])] = max(peak[int(parts[0])], int(parts[1]))
    return dict(peak)
rows = {}
for name in ["scale_1gpu", "scale_2gpu", "quality_1gpu", "quality_2gpu", "resume_1gpu"]:
    train = load(name, "train")
    row = {"wall_s": float(open(os.path.join(out, f"{name}.wall")).read()), "peak_mib_per_gpu": peak_mib(name)}
    if train:
        seconds = train.get("seconds", {})
        steps = train.get("steps", {})
        row["fine_seconds"] = seconds.get("fine") if isinstance(seconds, dict) else None
        row["fine_steps"] = steps.get("fine") if isinstance(steps, dict) else None
        if row["fine_seconds"] and row["fine_steps"]:
            row["fine_steps_per_s"] = row["fine_steps"] / row["fine_seconds"]
        row["gaussians"] = train.get("gaussians")
    ev = load(name, "eval")
    if ev:
        row["test_psnr"] = ev.get("mean", {}).get("psnr")
    rows[name] = row
summary = {"runs": rows}
a, b = rows["scale_1gpu"].get("fine_steps_per_s"), rows["scale_2gpu"].get("fine_steps_per_s")
if a and b:
    summary["scaling_2gpu_over_1gpu"] = b / a
q1, q2 = rows["quality_1gpu"], rows["quality_2gpu"]
summary["quality_wall_ratio_2gpu_over_1gpu"] = q2["wall_s"] / q1["wall_s"]
if q1.get("test_psnr") and q2.get("test_psnr"):
    summary["quality_psnr_2gpu_minus_1gpu"] = q2["test_psnr"] - q1["test_psnr"]
if q2.get("test_psnr") and rows["resume_1gpu"].get("test_psnr"):
    summary["resume_psnr_minus_straight_2gpu"] = rows["resume_1gpu"]["test_psnr"] - q2["test_psnr"]
print(json.dumps(summary, indent=1))
PY
