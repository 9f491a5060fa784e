#!/usr/bin/env bash
# The two commands of the README.
#   ./atex.sh demo   install Debian packages, build, run the toolkit on the bundled sample
#   ./atex.sh test   install Debian packages (and the test tools), build, run every test
# Both are idempotent: packages already installed are not reinstalled, builds are incremental.
set -euo pipefail
cd "$(dirname "$0")"
ROOT=$(pwd)
JOBS=${ATEX_JOBS:-$(nproc)}
BUILD=${ATEX_BUILD_DIR:-build}

# Debian packages the build needs (README, "Dependencies", says why each is here).
BUILD_PACKAGES=(build-essential cmake pkg-config libzstd-dev libeigen3-dev libdraco-dev libtinygltf-dev
  nlohmann-json3-dev libopenexr-dev libgtest-dev libcli11-dev libmeshoptimizer-dev libwebp-dev libpng-dev libjpeg-dev
  zlib1g-dev libbenchmark-dev python3-dev pybind11-dev libavformat-dev libavcodec-dev libswscale-dev libavutil-dev)
# Extra packages for the full test suite: clang for the sanitizer/libFuzzer build, chromium for the
# third-party checks in a headless browser (Babylon.js), matplotlib (Debian's python3) for the chart tests,
# numpy and pytest for the Python module's tests (python/tests, run by ctest), pip and venv for its
# build-backend test and `pip install .` (docs/python.md); the ffmpeg command encodes the N3DV .mp4 test videos.
TEST_PACKAGES=(clang libclang-rt-14-dev libomp-dev chromium python3-matplotlib python3-numpy python3-pytest
  python3-pip python3-venv ffmpeg)
# Node.js and npm run the glTF-Validator and the SPZ decoder. Many machines already carry a Node.js whose
# package bundles npm (NodeSource's "nodejs" conflicts with Debian's "npm"), so Debian's are installed only
# when the commands are missing.
NODE_PACKAGES=(nodejs npm)

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi; }

install_packages() {
  local missing=()
  for p in "$@"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "== installing: ${missing[*]}"
    as_root apt-get update -q
    DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -q --no-install-recommends "${missing[@]}"
  fi
}

configure_and_build() {
  cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release "$@"
  cmake --build "$BUILD" -j "$JOBS"
}

verb=${1:-}
case "$verb" in
  demo)
    install_packages "${BUILD_PACKAGES[@]}"
    configure_and_build
    "$ROOT/samples/run_demo.sh" "$BUILD/bin/atex"
    ;;
  test)
    install_packages "${BUILD_PACKAGES[@]}" "${TEST_PACKAGES[@]}"
    if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
      install_packages "${NODE_PACKAGES[@]}"
    fi
    configure_and_build
    # Third-party checkers from npm (glTF-Validator, Babylon.js + playwright-core, an SPZ decoder), pinned by
    # each folder's package-lock.json.
    for installer in "$ROOT"/tests/*/install.sh; do
      [ -x "$installer" ] && "$installer"
    done
    export ATEX_REQUIRE_DATA=${ATEX_REQUIRE_DATA:-1}
    ctest --test-dir "$BUILD" --output-on-failure -j "$JOBS"
    # Hostile-input suite under AddressSanitizer + UBSan, and the libFuzzer targets, built with clang.
    [ -x "$ROOT/tests/sanitize.sh" ] && "$ROOT/tests/sanitize.sh" "${BUILD}-asan"
    echo "== all tests passed"
    ;;
  *)
    echo "usage: $0 demo|test" >&2
    exit 2
    ;;
esac
