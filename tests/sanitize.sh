#!/usr/bin/env bash
# Hostile-input suite under AddressSanitizer + UndefinedBehaviorSanitizer, then a
# short libFuzzer run of every tests/fuzz/fuzz_*.cc target.
#
#   tests/sanitize.sh BUILD_DIR
#
# Configures a clang build in BUILD_DIR (-DATEX_SANITIZE=ON -DATEX_FUZZ=ON
# -DATEX_CUDA=OFF -DATEX_BENCHMARKS=OFF), builds the tests labelled `hostile` and
# every fuzz target, runs the tests, then each fuzzer for ATEX_FUZZ_SECONDS
# (default 20) seeded from tests/fuzz/corpus/<name>/, ATEX_JOBS at a time.
# Exit status 0 only if every test passed and no fuzzer found a crash, leak,
# timeout or out-of-memory. Crash inputs are kept in BUILD_DIR/fuzz-artifacts/.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:?usage: tests/sanitize.sh BUILD_DIR}
JOBS=${ATEX_JOBS:-$(nproc)}
FUZZ_SECONDS=${ATEX_FUZZ_SECONDS:-20}
START=$(date +%s)
say() { echo "== sanitize [$(( $(date +%s) - START ))s] $*"; }

for tool in clang clang++; do
  command -v "$tool" >/dev/null || { echo "sanitize.sh: $tool not found (Debian: clang libclang-rt-14-dev)" >&2; exit 1; }
done

say "configure $BUILD (clang, ASan+UBSan, libFuzzer)"
# -O1 and line tables only: sanitizer-friendly, and much quicker to compile than -O2 -g.
mkdir -p "$BUILD"
CC=clang CXX=clang++ cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
  -DATEX_SANITIZE=ON -DATEX_FUZZ=ON -DATEX_CUDA=OFF -DATEX_BENCHMARKS=OFF -DATEX_TESTS=ON >"$BUILD/configure.log" 2>&1 \
  || { cat "$BUILD/configure.log"; exit 1; }

# Hostile-input tests: every CTest test labelled `hostile` (the test name is its target).
hostile_tests() { ctest --test-dir "$BUILD" -N -L hostile | sed -n 's/^ *Test *#[0-9]*: *//p'; }
# Fuzz targets: one per tests/fuzz/fuzz_*.cc.
FUZZERS=()
for source in "$ROOT"/tests/fuzz/fuzz_*.cc; do
  [ -e "$source" ] && FUZZERS+=("$(basename "$source" .cc)")
done
mapfile -t TESTS < <(hostile_tests)
say "build ${#TESTS[@]} tests (${TESTS[*]}) and ${#FUZZERS[@]} fuzzers (${FUZZERS[*]})"
cmake --build "$BUILD" -j "$JOBS" --target "${TESTS[@]}" "${FUZZERS[@]}"
# The build may have re-run CMake (a changed sources.cmake); build tests that appeared.
mapfile -t MORE < <(comm -13 <(printf '%s\n' "${TESTS[@]}" | sort) <(hostile_tests | sort))
if [ ${#MORE[@]} -gt 0 ]; then
  say "build ${#MORE[@]} more tests (${MORE[*]})"
  cmake --build "$BUILD" -j "$JOBS" --target "${MORE[@]}"
fi

# LeakSanitizer needs ptrace; where the sandbox forbids it, run without leak checks.
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
if [ -z "${ASAN_OPTIONS:-}" ]; then
  if ASAN_OPTIONS=detect_leaks=1 "$BUILD/fuzz/${FUZZERS[0]:-none}" -runs=1 </dev/null >/dev/null 2>&1 || [ ${#FUZZERS[@]} -eq 0 ]; then
    export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
  else
    say "LeakSanitizer unavailable here: leak checks off"
    export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1
  fi
fi

say "run the hostile-input tests under ASan+UBSan"
TESTS_OK=1
ctest --test-dir "$BUILD" -L hostile --output-on-failure -j "$JOBS" || TESTS_OK=0

say "fuzz each target for ${FUZZ_SECONDS}s"
WORK="$BUILD/fuzz-work"
ARTIFACTS="$BUILD/fuzz-artifacts"
rm -rf "$WORK"
mkdir -p "$WORK" "$ARTIFACTS"
run_fuzzer() {
  local name=$1 reader=${1#fuzz_}
  local seeds="$ROOT/tests/fuzz/corpus/$reader"
  mkdir -p "$WORK/$name.corpus"
  local corpora=("$WORK/$name.corpus")  # new inputs go here, never into the source tree
  [ -d "$seeds" ] && corpora+=("$seeds")
  "$BUILD/fuzz/$name" -max_total_time="$FUZZ_SECONDS" -rss_limit_mb=2048 -timeout=20 -print_final_stats=1 \
    -artifact_prefix="$ARTIFACTS/$name-" "${corpora[@]}" >"$WORK/$name.log" 2>&1
}
declare -A PIDS=()
FAILED=()
for name in "${FUZZERS[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$JOBS" ]; do sleep 1; done
  run_fuzzer "$name" &
  PIDS[$name]=$!
done
for name in "${FUZZERS[@]}"; do
  if wait "${PIDS[$name]}"; then
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$WORK/$name.log" | tail -1)
    say "$name: ok (${runs:-?} inputs)"
  else
    FAILED+=("$name")
    say "$name: FAILED; log tail:"
    tail -40 "$WORK/$name.log"
  fi
done
STATUS=0
if [ "$TESTS_OK" != 1 ]; then
  say "hostile-input tests FAILED (see above)"
  STATUS=1
fi
if [ ${#FAILED[@]} -gt 0 ]; then
  say "fuzzers that failed: ${FAILED[*]} (inputs in $ARTIFACTS)"
  STATUS=1
fi
[ $STATUS = 0 ] && say "all hostile-input tests and fuzzers passed"
exit $STATUS
