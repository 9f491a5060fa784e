#!/usr/bin/env bash
# Fit speed and quality A/B on one GPU (issue 23): Panoptic basketball uniform and adaptive
# models fitted to 25 % of the uniform file, with the current tree (into $BUILD; at its defaults
# and with --step-growth 1) and .oldsrc (into build-old: `git archive COMMIT | tar -x -C .oldsrc`),
# in one call, one after the other on the same GPU. Each fit is timed (wall seconds of the process) and its output evaluated on
# the test views; outputs are checked against the budget and with `atex verify`.
#
#   bench/device/fit_panoptic.sh OUT_DIR [UNIFORM.atex ADAPTIVE.atex | --train-only]
#
# Without models it trains short ones into out/fitp (--train-only: only that, and no old build)
# with the current tree (shortened stage 1 of common.sh without fast-object Gaussians, which the
# old CLI cannot read, then FITP_STAGE2_STEPS (default 1,200) stage-2 steps uniform and adaptive
# at the same time on the GPU, growth at 10 % and 20 % of them), while .oldsrc builds on the CPU.
# FITP_CONFIGS picks the fitters (default "old new-fixed-steps new"; new-pN: the current tree with
# --parallel-candidates N; prev: .prevsrc, another commit, built like .oldsrc into build-prev),
# FITP_MODELS the models and
# their order (default "uniform adaptive"). Each row has the fit's wall seconds and its process's
# user and system CPU seconds. Results:
# OUT_DIR/fit_panoptic.jsonl (one row per fit), a table on stdout, and OUT_DIR/fitp.tgz (rows,
# reports, logs: one file, as a device call returns only a few).
source "$(dirname "$0")/common.sh"
out=$1
OLD=build-old
models=out/fitp
mkdir -p "$out" "$models"
jobs=$(nproc)
stage2_steps=${FITP_STAGE2_STEPS:-1200}
read -r -a fitters <<< "${FITP_CONFIGS:-old new-fixed-steps new}"
build_tree . "$BUILD" "$jobs" atex_cli > out/build_new.log 2>&1 || { tail -5 out/build_new.log; exit 1; }
train_only=0
[ "${2:-}" = --train-only ] && train_only=1
old_pid=
if [ $train_only = 0 ]; then
  (  # on the CPU while stage 1 trains
    [[ " ${fitters[*]} " != *" old "* ]] || build_old "$jobs" > out/build_old.log 2>&1 || exit 1
    [[ " ${fitters[*]} " != *" prev "* ]] || build_old "$jobs" prev > out/build_prev.log 2>&1 || exit 1
  ) &
  old_pid=$!
fi
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1 | tee "$out/gpu.txt"

if [ $# -ge 3 ]; then
  uniform=$2
  adaptive=$3
else
  # Without time-local fast-object Gaussians: .oldsrc's CLI (72791af) predates their chunk
  # (GTWN) and refuses models that have them (E9), so the A/B needs models without.
  train_short_stage1 "$models" 0 --set stage1.fast_objects.enabled=false
  train_pids=()
  for textures in uniform adaptive; do  # both at once: the GPU has room, and these are not timed
    [ -f "$models/$textures.atex" ] && continue
    growth=()
    [ "$textures" = adaptive ] && growth=(--set "stage2.growth_steps=[$((stage2_steps / 10)),$((stage2_steps / 5))]")
    "$atex" train --data "$bb" --stage 2 --init "$models/stage1.atex" --textures "$textures" \
      --set stage2.iterations="$stage2_steps" "${growth[@]}" --out "$models/$textures.atex" --json \
      > "$models/$textures.train.json" 2> "$models/$textures.log" &
    train_pids+=($!)
  done
  # Only the training jobs: a bare `wait` (no job left to name when both models exist from an
  # earlier call on the same machine) would also reap the old build, whose wait below then fails.
  [ ${#train_pids[@]} -eq 0 ] || wait "${train_pids[@]}" || true
  for textures in uniform adaptive; do
    [ -f "$models/$textures.atex" ] || { tail -5 "$models/$textures.log"; exit 1; }
  done
  uniform=$models/uniform.atex
  adaptive=$models/adaptive.atex
  [ $train_only = 1 ] && exit 0
fi
if [ -n "$old_pid" ]; then
  wait "$old_pid" || { tail -5 out/build_old.log out/build_prev.log 2> /dev/null; exit 1; }
fi
budget=$(( $(stat -c %s "$uniform") / 4 ))
rows=$out/fit_panoptic.jsonl
: > "$rows"
# Three fitters per model: the old CLI; the new one with fixed steps (--step-growth 1: the old
# plan, so the same output, sped up by what does not change the plan); the new one at its
# defaults (growing steps).
configs=()
for f in "${fitters[@]}"; do
  case $f in
    old) configs+=("$OLD|old|") ;;
    prev) configs+=("build-prev|prev|") ;;
    new-fixed-steps) configs+=("$BUILD|new-fixed-steps|--step-growth 1") ;;
    new) configs+=("$BUILD|new|") ;;
    new-p[0-9]*) configs+=("$BUILD|$f|--parallel-candidates ${f#new-p}") ;;  # e.g. new-p2: two at once
    *) echo "unknown fitter $f" >&2; exit 2 ;;
  esac
done
read -r -a fit_models <<< "${FITP_MODELS:-uniform adaptive}"
# A fit still running after FITP_FIT_TIMEOUT seconds (default 120; they take 10-30 s) is stuck,
# not slow: what it is doing is written to NAME.stuck.txt (its threads' states and CPU use, the
# GPU's, and every thread's stack where the machine has gdb or cuda-gdb), then it is killed and
# its row says so ("failed"), and the other fits go on.
fit_limit=${FITP_FIT_TIMEOUT:-120}
dump_fit() {
  local pid=$1 debugger
  echo "== threads"; top -H -b -n 1 -p "$pid" 2>&1 | head -80
  echo "== state and wait channel per thread"
  for t in /proc/"$pid"/task/*; do echo "${t##*/} $(cut -d' ' -f3 "$t/stat") $(cat "$t/wchan" 2>/dev/null)"; done
  echo "== GPU"; nvidia-smi 2>&1 | head -30
  debugger=$(command -v gdb || command -v cuda-gdb || true)
  [ -z "$debugger" ] && [ -x /usr/local/cuda/bin/cuda-gdb ] && debugger=/usr/local/cuda/bin/cuda-gdb
  if [ -n "$debugger" ]; then
    echo "== stacks ($debugger)"; timeout 90 "$debugger" -p "$pid" -batch -ex "thread apply all bt" 2>&1 | head -3000
  fi
}
for model in "${fit_models[@]}"; do
  input=${!model}
  for config in "${configs[@]}"; do
    IFS='|' read -r bin label extra <<< "$config"
    name=$out/${model}_$label
    rm -f "$name.atex"
    start=$(date +%s.%N)
    # The process's CPU seconds (user, system) beside its wall time.
    TIMEFORMAT='%U %S'
    (
      set +e  # a failing probe of the stuck process must not keep it from being killed
      sleep "$fit_limit"
      pid=$(pgrep -f -- " $name.atex " | head -1)
      if [ -n "$pid" ]; then
        dump_fit "$pid" > "$name.stuck.txt" 2>&1
        kill -9 "$pid"
      fi
    ) 2> /dev/null &  # quiet when stopped early (the usual case): its sleep is killed
    watcher=$!
    fit_status=0
    # shellcheck disable=SC2086  # $extra is a list of words
    { time "$bin/bin/atex" fit "$input" "$name.atex" --budget "$budget" --data "$bb" --json $extra \
      > "$name.fit.json" 2> "$name.fit.log"; } 2> "$name.cpu.txt" || fit_status=$?
    end=$(date +%s.%N)
    pkill -P "$watcher" 2> /dev/null || true
    kill "$watcher" 2> /dev/null || true
    wait "$watcher" 2> /dev/null || true
    if [ "$fit_status" != 0 ]; then
      python3 -c 'import json, sys; print(json.dumps({"model": sys.argv[1], "build": sys.argv[2], "failed": True,
        "exit_status": int(sys.argv[3]), "stuck": sys.argv[4] == "1", "wall_s": round(float(sys.argv[6]) - float(sys.argv[5]), 2)}))' \
        "$model" "$label" "$fit_status" "$([ -f "$name.stuck.txt" ] && echo 1 || echo 0)" "$start" "$end" >> "$rows"
      tail -3 "$name.fit.log" >&2
      continue
    fi
    # A file that an earlier fit of this call wrote already (same bytes) has that fit's evaluation.
    sha=$(sha256sum "$name.atex" | cut -d' ' -f1)
    if [ -f "$out/eval_$sha.json" ]; then
      cp "$out/eval_$sha.json" "$name.eval.json"
    else
      "$BUILD/bin/atex" eval "$name.atex" --data "$bb" --json > "$name.eval.json"
      cp "$name.eval.json" "$out/eval_$sha.json"
    fi
    verified=true
    "$BUILD/bin/atex" verify "$name.atex" > /dev/null 2>&1 || verified=false
    python3 - "$name" "$model" "$label" "$budget" "$start" "$end" "$verified" >> "$rows" <<'PY'
import hashlib, json, os, sys
name, model, label, budget, start, end, verified = sys.argv[1:]
user_s, sys_s = (float(x) for x in open(name + ".cpu.txt").read().split()[-2:])
fit = json.load(open(name + ".fit.json"))
ev = json.load(open(name + ".eval.json"))
size = os.path.getsize(name + ".atex")
timing = fit.get("plan_timing", [{}])[0]
print(json.dumps({"model": model, "build": label, "budget_bytes": int(budget), "bytes": size,
                  "within_budget": size <= int(budget), "verify": verified == "true",
                  "wall_s": round(float(end) - float(start), 2), "user_s": user_s, "sys_s": sys_s,
                  "fit_s": fit.get("seconds", {}).get("fit"),
                  "measurements": timing.get("measurements"), "plan_seconds": timing.get("seconds"),
                  "apply_plan_seconds": timing.get("apply_plan_seconds"),
                  "refill_seconds": timing.get("refill_seconds"), "refill_encodes": timing.get("refill_encodes"),
                  "refill_encode_seconds": timing.get("refill_encode_seconds"),
                  "refill_state_seconds": timing.get("refill_state_seconds"), "moves": len(fit.get("moves", [])),
                  "test_psnr": ev["mean"]["psnr"],
                  "gaussians": fit.get("levers", {}).get("gaussians", {}).get("after"),
                  "sha256": hashlib.sha256(open(name + ".atex", "rb").read()).hexdigest(),
                  "prepared_ahead": timing.get("prepared_ahead"), "prepared_unused": timing.get("prepared_unused"),
                  "next_steps_prepared": timing.get("next_steps_prepared"),
                  "next_steps_used": timing.get("next_steps_used"),
                  "seconds": fit.get("seconds")}))
PY
  done
done
python3 - "$rows" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print("| model | build | wall s | fit s | measurements | bytes | within | verify | test PSNR |")
print("|---|---|---:|---:|---:|---:|---|---|---:|")
for r in rows:
    if r.get("failed"):
        print(f"| {r['model']} | {r['build']} | {r['wall_s']} | failed (exit {r['exit_status']}"
              f"{', stuck: see .stuck.txt' if r['stuck'] else ''}) | | | | | |")
        continue
    print(f"| {r['model']} | {r['build']} | {r['wall_s']} | {r['fit_s']} | {r['measurements']} | {r['bytes']} "
          f"| {r['within_budget']} | {r['verify']} | {r['test_psnr']:.4f} |")
PY
tar -czf "$out/fitp.tgz" "$out"/*.jsonl "$out"/*.json "$out"/*.log "$out"/*.stuck.txt "$out/gpu.txt" "$models"/*.json "$models"/*.log \
  2> /dev/null || true
