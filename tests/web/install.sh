#!/usr/bin/env bash
# Installs the pinned npm packages of the browser and validator checks (package-lock.json)
# into tests/web/node_modules. Debian's nodejs, npm and chromium come from atex.sh's test verb.
set -euo pipefail
cd "$(dirname "$0")"
if ! command -v npm >/dev/null 2>&1; then
  echo "tests/web/install.sh: npm is not installed (apt-get install nodejs npm)" >&2
  exit 1
fi
# No network when the installed tree was made from this very lock file.
if cmp -s package-lock.json node_modules/.atex-lock-stamp 2>/dev/null; then
  echo "== npm packages of tests/web are up to date"
  exit 0
fi
echo "== installing npm packages of tests/web (package-lock.json)"
npm ci --no-audit --no-fund
cp package-lock.json node_modules/.atex-lock-stamp
