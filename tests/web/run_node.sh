#!/usr/bin/env bash
# Runs one node check of tests/web. A missing tool is a failure in CI (ATEX_REQUIRE_DATA=1)
# and a skip (exit 77, CTest's SKIP_RETURN_CODE) elsewhere.
set -u
script=$1
shift
missing() {
  if [ "${ATEX_REQUIRE_DATA:-0}" = 1 ]; then
    echo "FAIL: $1" >&2
    exit 1
  fi
  echo "SKIP: $1" >&2
  exit 77
}
command -v node >/dev/null 2>&1 || missing "node is not installed (apt-get install nodejs npm)"
here=$(cd "$(dirname "$0")" && pwd)
[ -d "$here/node_modules" ] || missing "npm packages are missing: run tests/web/install.sh"
exec node "$script" "$@"
