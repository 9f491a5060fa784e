#!/usr/bin/env bash
# `atex fit` on N random budgets of one input: every output must be at or under its budget
# and pass `atex verify`. A benchmark script, not a CI test (N fits take minutes to hours).
#
#   bench/fit_random_budgets.sh [-n N] [-s SEED] [-k FIRST] [-c COUNT] [-u UPPER] [-a ATEX] [-i INPUT]
#                               [-j JOBS] [-o OUT] [-- FIT_ARGS...]
#
# Budgets are drawn uniformly in log space between the input's smallest reachable size
# (the E16 refusal names it; taken from one fit at 1 byte) and its file size, from a
# seeded generator, so a run is reproducible. Several budgets share no plan here: each is
# one `atex fit` process, as a user would run it. Prints a summary line and writes the
# rows (index, budget, bytes, seconds, verify) to OUT (default out/fit_random_budgets.csv).
# -k FIRST fits only the budgets from index FIRST on (of the same N drawn): it finishes a
# run that was cut short without changing which budgets the whole run covers; -c COUNT fits only
# COUNT budgets from FIRST (several instances, e.g. one per GPU, share one run of N). -u UPPER
# draws below UPPER bytes instead of the file size (e.g. the band just above the smallest size).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

n=1000
seed=1
atex=build/bin/atex
input=samples/lego_adaptive_2MiB.atex
jobs=1
first=0
count=
upper=
out=out/fit_random_budgets.csv
while [ $# -gt 0 ]; do
  case $1 in
    -n) n=$2; shift 2 ;;
    -s) seed=$2; shift 2 ;;
    -k) first=$2; case $first in ''|*[!0-9]*) echo "-k takes an index" >&2; exit 2 ;; esac; shift 2 ;;
    -c) count=$2; case $count in ''|*[!0-9]*) echo "-c takes a count" >&2; exit 2 ;; esac; shift 2 ;;
    -u) upper=$2; shift 2 ;;
    -a) atex=$2; shift 2 ;;
    -i) input=$2; shift 2 ;;
    -j) jobs=$2; shift 2 ;;
    -o) out=$2; shift 2 ;;
    --) shift; break ;;
    -h|--help) sed -n 2,16p "$0"; exit 0 ;;
    *) echo "unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
fit_args=("$@")
mkdir -p "$(dirname "$out")"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

size=$(stat -c %s "$input")
if [ -n "$upper" ]; then
  case $upper in ''|*[!0-9]*) echo "-u takes a whole number of bytes, not '$upper'" >&2; exit 2 ;; esac
  size=$upper
fi
# -k finishes another run: its rows stay where they are, these go to a file of their own.
if [ "$first" -gt 0 ] && [ -e "$out" ]; then
  echo "$out exists: with -k, write the remaining rows to a new file (-o) beside the first run's" >&2
  exit 2
fi
# The smallest reachable size: the refusal of a 1-byte budget names it.
set +e
refusal=$("$atex" fit "$input" "$work/min.atex" --budget 1 "${fit_args[@]}" 2>&1 >/dev/null)
set -e
minimum=$(printf '%s\n' "$refusal" | grep -o 'from this input, [0-9]*' | grep -o '[0-9]*$' || true)
if [ -z "$minimum" ]; then
  echo "could not read the smallest reachable size from: $refusal" >&2
  exit 1
fi
if [ "$size" -le "$minimum" ]; then
  echo "the upper end $size is not above the smallest reachable size $minimum" >&2
  exit 2
fi
python3 - "$n" "$seed" "$minimum" "$size" > "$work/budgets" <<'EOF'
import math, random, sys
n, seed, lo, hi = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
rng = random.Random(seed)
for _ in range(n):
    print(int(math.exp(rng.uniform(math.log(lo), math.log(hi)))))
EOF

fit_one() {  # BUDGET INDEX
  local budget=$1 k=$2 file="$work/fit_$2.atex" start end ok=1 bytes
  start=$(date +%s.%N)
  if ! "$atex" fit "$input" "$file" --budget "$budget" "${fit_args[@]}" > /dev/null 2> "$work/err_$k"; then
    echo "$k,$budget,-1,0,fit-failed"
    return
  fi
  end=$(date +%s.%N)
  bytes=$(stat -c %s "$file")
  "$atex" verify "$file" > /dev/null 2>&1 || ok=0
  echo "$k,$budget,$bytes,$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.2f", b - a }'),$([ $ok = 1 ] && echo verified || echo verify-failed)"
  rm -f "$file"
}

echo "index,budget,bytes,seconds,check" > "$out"
k=0
while read -r budget; do
  if [ "$k" -lt "$first" ]; then k=$((k + 1)); continue; fi
  if [ -n "$count" ] && [ "$k" -ge $((first + count)) ]; then break; fi
  fit_one "$budget" "$k" >> "$out" &
  k=$((k + 1))
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n; done
done < "$work/budgets"
wait

python3 - "$out" "$input" "$minimum" "$size" <<'EOF'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
over = [r for r in rows if int(r["bytes"]) > int(r["budget"])]
failed = [r for r in rows if r["check"] != "verified"]
secs = sorted(float(r["seconds"]) for r in rows if r["check"] == "verified")
median = secs[len(secs) // 2] if secs else float("nan")
print(f"{len(rows)} budgets in [{sys.argv[3]}, {sys.argv[4]}] bytes of {sys.argv[2]}: "
      f"{len(over)} over budget, {len(failed)} failed (fit or verify); "
      f"fit seconds median {median:.2f}, max {max(secs) if secs else float('nan'):.2f}")
sys.exit(1 if over or failed else 0)
EOF
