#!/usr/bin/env bash
# Installs the third-party splat writers of the reader tests (npm
# @playcanvas/splat-transform, gsplat, @mkkellogg/gaussian-splats-3d and its peer
# three, pinned in package.json and package-lock.json) that the CTest test
# converter_websplat_test runs through make_fixtures.mjs.
# Idempotent: nothing is downloaded when the pinned versions are already installed.
set -euo pipefail
cd "$(dirname "$0")"
ok=1
for pkg in @playcanvas/splat-transform gsplat @mkkellogg/gaussian-splats-3d three; do
  wanted=$(node -p "require('./package.json').dependencies['$pkg']")
  installed=$(node -p "try { require('./node_modules/$pkg/package.json').version } catch (e) { '' }")
  [ "$installed" = "$wanted" ] || ok=0
done
if [ "$ok" = 1 ]; then
  exit 0
fi
npm ci --no-audit --no-fund --loglevel=error
