#!/usr/bin/env bash
# Lines past 120 columns in the library, the CUDA backend, the converters and the tools
# (.clang-format's ColumnLimit), as FILE:LINE: LENGTH, and their count on the last line.
#   bench/format_check.sh [--fix]   --fix: clang-format exactly those lines (clang-format --lines)
# Exit status 1 when a line is past the limit (after --fix: when one still is, e.g. a long URL).
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
# shellcheck disable=SC2086  # the file list is words
awk 'length($0) > 120 { print FILENAME ":" FNR ": " length($0); n++ } END { print n + 0 " lines past 120 columns"; exit (n > 0) }' $files
