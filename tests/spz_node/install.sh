#!/usr/bin/env bash
# Installs the independent SPZ decoder (npm @adobe/spz, pinned in package.json and
# package-lock.json) that the CTest test converter_spz_node_test runs.
# Idempotent: nothing is downloaded when the pinned version is already installed.
set -euo pipefail
cd "$(dirname "$0")"
wanted=$(node -p "require('./package.json').dependencies['@adobe/spz']")
installed=$(node -p "try { require('./node_modules/@adobe/spz/package.json').version } catch (e) { '' }")
if [ "$installed" = "$wanted" ]; then
  exit 0
fi
npm ci --no-audit --no-fund --loglevel=error
