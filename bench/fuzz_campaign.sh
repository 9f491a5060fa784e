#!/usr/bin/env bash
# Fuzzing at depth (issue 24): every libFuzzer target of tests/fuzz, one after the other,
# each on all cores (libFuzzer's -fork mode) for a given time; then the new inputs that
# add coverage are merged (minimised) into the seed corpus tests/fuzz/corpus/<reader>/,
# crash / timeout / out-of-memory inputs are copied there too (so that tests/sanitize.sh
# fails on them until they are fixed: they are the regression inputs), and a table of
# executions, coverage and findings per target is printed and written as Markdown and
# JSON.
#
#   bench/fuzz_campaign.sh [--seconds S] [--runs N] [--jobs J] [--build DIR] [--prebuilt]
#                          [--targets a,b] [--out DIR] [--no-merge]
#
#   --seconds S   time per target (default 60): the most a target runs
#   --runs N      stop a target once its processes have executed N inputs in all (libFuzzer's
#                 -runs, summed over the fork; the issue's depth is 10000000), or at S seconds
#   --jobs J      parallel fuzzing processes per target (default: every core, nproc)
#   --build DIR   the clang ASan+UBSan+libFuzzer build (default build-fuzz; configured as
#                 tests/sanitize.sh does when missing)
#   --targets     comma-separated subset (fuzz_atex,fuzz_ply,...; default all tests/fuzz/fuzz_*.cc)
#   --out DIR     where fuzz_campaign.{md,json} and the logs go (default BUILD/fuzz-campaign)
#   --prebuilt    use the targets already in DIR/fuzz as they are: no clang needed (for a
#                 machine without clang, e.g. the lent GPU machines, with binaries built here;
#                 bench/device/fuzz_kit.sh packs them with the libraries they load)
#   --corpus DIR  the seed corpus, one folder per reader, into which new inputs are merged
#                 (default tests/fuzz/corpus)
#   --no-merge    leave the corpus untouched
#
# Needs clang and libclang-rt (Debian: clang libclang-rt-14-dev) unless --prebuilt. No GPU. The exit status is
# 1 when any target found a crash, leak, timeout or out-of-memory input.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SECONDS_PER_TARGET=60
RUNS=-1
PREBUILT=0
JOBS=$(nproc)
BUILD=build-fuzz
TARGETS=""
OUT=""
CORPUS=""
MERGE=1
while [ $# -gt 0 ]; do
  case $1 in
    --seconds) SECONDS_PER_TARGET=$2; shift 2 ;;
    --runs) RUNS=$2; shift 2 ;;
    --prebuilt) PREBUILT=1; shift ;;
    --jobs) JOBS=$2; shift 2 ;;
    --build) BUILD=$2; shift 2 ;;
    --targets) TARGETS=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --corpus) CORPUS=$2; shift 2 ;;
    --no-merge) MERGE=0; shift ;;
    -h|--help) sed -n '2,31p' "$0"; exit 0 ;;
    *) echo "fuzz_campaign.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
case $SECONDS_PER_TARGET in ''|*[!0-9]*) echo "fuzz_campaign.sh: --seconds must be a whole number" >&2; exit 2 ;; esac
case $RUNS in -1) ;; ''|*[!0-9]*|0) echo "fuzz_campaign.sh: --runs must be a positive whole number" >&2; exit 2 ;; esac
case $JOBS in ''|*[!0-9]*|0) echo "fuzz_campaign.sh: --jobs must be a positive whole number" >&2; exit 2 ;; esac
OUT=${OUT:-$BUILD/fuzz-campaign}
CORPUS=${CORPUS:-$ROOT/tests/fuzz/corpus}
START=$(date +%s)
say() { echo "== fuzz campaign [$(( $(date +%s) - START ))s] $*"; }
if [ "$PREBUILT" = 0 ]; then
  for tool in clang clang++; do
    command -v "$tool" >/dev/null || { echo "fuzz_campaign.sh: $tool not found (Debian: clang libclang-rt-14-dev)" >&2; exit 1; }
  done
fi

ALL=()
for source in "$ROOT"/tests/fuzz/fuzz_*.cc; do ALL+=("$(basename "$source" .cc)"); done
if [ -n "$TARGETS" ]; then IFS=, read -r -a RUN <<<"$TARGETS"; else RUN=("${ALL[@]}"); fi
for name in "${RUN[@]}"; do
  [ -e "$ROOT/tests/fuzz/$name.cc" ] || { echo "fuzz_campaign.sh: no target $name (have: ${ALL[*]})" >&2; exit 2; }
done

if [ "$PREBUILT" = 1 ]; then
  for name in "${RUN[@]}"; do
    [ -x "$BUILD/fuzz/$name" ] || { echo "fuzz_campaign.sh: --prebuilt but $BUILD/fuzz/$name is missing" >&2; exit 1; }
  done
elif [ ! -f "$BUILD/CMakeCache.txt" ]; then
  say "configure $BUILD (clang, ASan+UBSan, libFuzzer; as tests/sanitize.sh)"
  mkdir -p "$BUILD"
  CC=clang CXX=clang++ cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
    -DATEX_SANITIZE=ON -DATEX_FUZZ=ON -DATEX_CUDA=OFF -DATEX_BENCHMARKS=OFF -DATEX_TESTS=ON \
    >"$BUILD/configure.log" 2>&1 || { cat "$BUILD/configure.log"; exit 1; }
fi
if [ "$PREBUILT" = 0 ]; then
  say "build ${#RUN[@]} targets: ${RUN[*]}"
  cmake --build "$BUILD" -j "$JOBS" --target "${RUN[@]}" >"$BUILD/fuzz-build.log" 2>&1 || { tail -40 "$BUILD/fuzz-build.log"; exit 1; }
fi

mkdir -p "$OUT"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# LeakSanitizer needs ptrace; where the sandbox forbids it, run without leak checks.
if ! "$BUILD/fuzz/${RUN[0]}" -runs=1 </dev/null >/dev/null 2>&1; then
  export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1
  say "LeakSanitizer unavailable here: leak checks off"
fi

ROWS=()
FOUND=0
for name in "${RUN[@]}"; do
  reader=${name#fuzz_}
  seeds="$CORPUS/$reader"
  work="$OUT/$name"
  rm -rf "$work"
  mkdir -p "$work/new" "$work/artifacts" "$seeds"
  seed_count=$(find "$seeds" -type f | wc -l)
  say "$name: ${SECONDS_PER_TARGET}s on $JOBS processes from $seed_count seeds"
  # -fork: JOBS child processes, crashes recorded and the campaign continues (-ignore_*).
  set +e
  "$BUILD/fuzz/$name" -fork="$JOBS" -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
    -max_total_time="$SECONDS_PER_TARGET" -runs="$RUNS" -rss_limit_mb=2048 -timeout=20 -print_final_stats=1 \
    -artifact_prefix="$work/artifacts/" "$work/new" "$seeds" >"$work/log" 2>&1
  status=$?
  set -e
  # Fork mode's progress lines: "#EXECS: cov: C ft: F corp: N exec/s: R oom/timeout/crash: a/b/c time: Ts ..."
  last=$(grep -E '^#[0-9]+: cov: ' "$work/log" | tail -1 || true)
  execs=$(sed -nE 's/^#([0-9]+): .*/\1/p' <<<"$last")
  cov=$(sed -nE 's/.* cov: ([0-9]+) .*/\1/p' <<<"$last")
  ft=$(sed -nE 's/.* ft: ([0-9]+) .*/\1/p' <<<"$last")
  otc=$(sed -nE 's#.*oom/timeout/crash: ([0-9]+/[0-9]+/[0-9]+).*#\1#p' <<<"$last")
  if [ -z "$last" ]; then  # a single run without fork lines (e.g. it crashed at once)
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/log" | tail -1)
    cov=$(grep -oE ' cov: [0-9]+' "$work/log" | tail -1 | grep -oE '[0-9]+' || true)
    ft=$(grep -oE ' ft: [0-9]+' "$work/log" | tail -1 | grep -oE '[0-9]+' || true)
  fi
  ooms=${otc%%/*}; rest=${otc#*/}; timeouts=${rest%%/*}; crashes=${rest#*/}
  artifacts=$(find "$work/artifacts" -type f | wc -l)
  findings=$artifacts
  if [ "$findings" -gt 0 ]; then
    FOUND=1
    # Every finding becomes a regression input beside the seeds (named by its content).
    for f in "$work/artifacts"/*; do
      cp "$f" "$seeds/regression-$(basename "$f" | cut -d- -f1)-$(sha1sum "$f" | cut -c1-16)"
    done
  elif [ $status -ne 0 ]; then
    FOUND=1
    findings="exit $status"
  fi
  added=0
  if [ "$MERGE" = 1 ] && [ -n "$(ls -A "$work/new")" ]; then
    before=$(find "$seeds" -type f | wc -l)
    "$BUILD/fuzz/$name" -merge=1 -rss_limit_mb=2048 -timeout=20 "$seeds" "$work/new" >"$work/merge.log" 2>&1 || true
    added=$(( $(find "$seeds" -type f | wc -l) - before ))
  fi
  corpus=$(find "$seeds" -type f | wc -l)
  row="$name|${execs:-0}|$SECONDS_PER_TARGET|$JOBS|${cov:-0}|${ft:-0}|$corpus|$added|${crashes:-0}|${timeouts:-0}|${ooms:-0}|$findings"
  ROWS+=("$row")
  say "$name: ${execs:-?} execs, cov ${cov:-?}, ft ${ft:-?}, corpus $corpus (+$added), crash/timeout/oom ${crashes:-0}/${timeouts:-0}/${ooms:-0}, findings $findings"
done

{
  echo "| target | execs | seconds | processes | coverage (edges) | features | corpus | merged | crashes | timeouts | ooms | findings |"
  echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"
  for row in "${ROWS[@]}"; do echo "| ${row//|/ | } |"; done
  echo
  runs_arg=""
  [ "$RUNS" != -1 ] && runs_arg=" --runs $RUNS"
  echo "Machine: $(nproc) cores, $(uname -srm); $(date -u +%Y-%m-%d); command: bench/fuzz_campaign.sh --seconds $SECONDS_PER_TARGET$runs_arg --jobs $JOBS"
} >"$OUT/fuzz_campaign.md"
python3 - "$OUT/fuzz_campaign.json" "${ROWS[@]}" <<'PY'
import json, sys
keys = ["target", "execs", "seconds", "processes", "coverage", "features", "corpus", "merged", "crashes",
        "timeouts", "ooms", "findings"]
rows = []
for line in sys.argv[2:]:
    values = line.split("|")
    row = dict(zip(keys, values))
    for k in keys[1:-1]:
        row[k] = int(row[k]) if row[k].isdigit() else row[k]
    rows.append(row)
json.dump({"targets": rows}, open(sys.argv[1], "w"), indent=2)
PY
cat "$OUT/fuzz_campaign.md"
say "table: $OUT/fuzz_campaign.md and .json"
if [ $FOUND = 1 ]; then
  say "FINDINGS: inputs copied into tests/fuzz/corpus/<reader>/regression-*; fix the reader, keep the input"
  exit 1
fi
