#!/usr/bin/env bash
# Lines past 120 columns in the library, the CUDA backend, the converters and the tools
# (.clang-format's ColumnLimit), as FILE:LINE: LENGTH, and their count; then functions over 120 lines
# and files over 500 lines there and in python/ (bench/function_length.py; test code is listed apart and
# never fails the check; a "long function:" / "long file:" comment with a reason exempts one).
#   bench/format_check.sh [--fix]   --fix: clang-format exactly the long lines (clang-format --lines)
# Exit status 1 when a line is past the limit (after --fix: when one still is, e.g. a long URL), or a
# function or file of non-test code is over its limit without a stated reason.
set -euo pipefail
cd "$(dirname "$0")/.."
fix=0
[ "${1:-}" = --fix ] && fix=1
files=$(git ls-files 'libatex/*.cc' 'libatex/*.h' 'kernels/*.cc' 'kernels/*.h' 'kernels/*.cu' 'kernels/*.cuh' \
  'converters/*.cc' 'converters/*.h' 'tools/*.cc' 'tools/*.h')
if [ $fix = 1 ]; then
  for f in $files; do
    lines=$(awk 'length($0) > 120 { printf " --lines=%d:%d", NR, NR }' "$f")
    # shellcheck disable=SC2086  # the --lines options are words
    [ -n "$lines" ] && clang-format -i $lines "$f"
  done
fi
columns=0
# Characters, not bytes (mawk counts bytes: "σ²" would count as four).
# shellcheck disable=SC2086  # the file list is words
python3 - $files <<'PY' || columns=1
import sys
n = 0
for path in sys.argv[1:]:
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            if len(line.rstrip("\n")) > 120:
                print("%s:%d: %d" % (path, number, len(line.rstrip("\n"))))
                n += 1
print("%d lines past 120 columns" % n)
sys.exit(1 if n else 0)
PY
lengths=0
python3 bench/function_length.py --files libatex kernels converters tools python || lengths=1
exit $((columns | lengths))
