#!/usr/bin/env bash
# The installed tree works for a user: `cmake --install` into a prefix inside the build
# folder, then a tiny project (tests/install/consumer) is configured with find_package(atex),
# built, and run on the bundled sample (it reads it and renders a view); the same program is
# built again with pkg-config alone. Also checks that the installed files are where the docs say.
#   tests/install/run_consumer.sh BUILD_DIR
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=$(cd "${1:?usage: run_consumer.sh BUILD_DIR}" && pwd)
WORK=$BUILD/install-test
PREFIX=$WORK/prefix
rm -rf "$WORK"
mkdir -p "$WORK"
cmake --install "$BUILD" --prefix "$PREFIX" >"$WORK/install.log"

libdir=$(sed -n 's/^libdir=\${prefix}\///p' "$(find "$PREFIX" -name atex.pc | head -1)")
for f in bin/atex include/atex/container.h include/atex/version.h include/atex/converters/convert.h \
         "$libdir/libatex.a" "$libdir/libatex_converters.a" "$libdir/pkgconfig/atex.pc" \
         "$libdir/cmake/atex/atexConfig.cmake" "$libdir/cmake/atex/atexConfigVersion.cmake" \
         "$libdir/cmake/atex/atexTargets.cmake"; do
  [ -e "$PREFIX/$f" ] || { echo "missing from the install: $f" >&2; exit 1; }
done
"$PREFIX/bin/atex" --version

# CMake: find_package(atex) with nothing but the prefix.
cmake -S "$ROOT/tests/install/consumer" -B "$WORK/consumer" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$PREFIX" ${CMAKE_CXX_COMPILER_LAUNCHER:+-DCMAKE_CXX_COMPILER_LAUNCHER=$CMAKE_CXX_COMPILER_LAUNCHER} \
  >"$WORK/consumer-configure.log" || { cat "$WORK/consumer-configure.log"; exit 1; }
cmake --build "$WORK/consumer" >"$WORK/consumer-build.log" || { cat "$WORK/consumer-build.log"; exit 1; }
"$WORK/consumer/atex_consumer" "$ROOT/samples/lego_adaptive_2MiB.atex"

# pkg-config: the same program from the .pc file alone (static libraries: --static).
export PKG_CONFIG_PATH=$PREFIX/$libdir/pkgconfig
# shellcheck disable=SC2046
${CXX:-c++} -O1 -o "$WORK/atex_consumer_pc" "$ROOT/tests/install/consumer/main.cc" \
  $(pkg-config --cflags atex) $(pkg-config --static --libs atex)
"$WORK/atex_consumer_pc" "$ROOT/samples/lego_adaptive_2MiB.atex"
echo "install consumer: ok"
