#!/usr/bin/env bash
# Packs the libFuzzer targets of a clang ASan+UBSan build made here (bench/fuzz_campaign.sh's
# build-fuzz) for a machine without clang, such as the lent GPU machines (16 cores, no clang):
# the binaries and every library they load that is not part of the C/C++ runtime, in one
# archive for a device call's `carry`.
#
#   bench/device/fuzz_kit.sh pack [BUILD [TARGETS]]   -> .fuzzkit/kit.tar.xz (git-ignored); TARGETS
#                                        (comma-separated, e.g. fuzz_gltf,fuzz_pth) packs only those
#   bench/device/fuzz_kit.sh unpack         -> .fuzzkit/build/fuzz/fuzz_* and .fuzzkit/lib, on the device
#
# On the device: LD_LIBRARY_PATH=.fuzzkit/lib bench/fuzz_campaign.sh --prebuilt --build .fuzzkit/build ...
# The sanitizer runtimes and libFuzzer are linked into each binary; the C library, libstdc++,
# libgcc_s and libm come from the device (newer than Debian 12's, and backward compatible).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
case ${1:-} in
  pack)
    build=${2:-build-fuzz}
    targets=${3:-}
    rm -rf .fuzzkit && mkdir -p .fuzzkit/stage/build/fuzz .fuzzkit/stage/lib
    for source in tests/fuzz/fuzz_*.cc; do
      name=$(basename "$source" .cc)
      [ -z "$targets" ] || [[ ",$targets," == *",$name,"* ]] || continue
      [ -x "$build/fuzz/$name" ] || { echo "fuzz_kit.sh: $build/fuzz/$name not built" >&2; exit 1; }
      cp "$build/fuzz/$name" .fuzzkit/stage/build/fuzz/
    done
    ldd .fuzzkit/stage/build/fuzz/* | awk '/=> \// {print $3}' | sort -u | while read -r lib; do
      case $(basename "$lib") in
        libc.so*|libm.so*|libpthread.so*|libdl.so*|librt.so*|ld-linux*|libstdc++.so*|libgcc_s.so*) ;;
        *) cp -L "$lib" .fuzzkit/stage/lib/ ;;
      esac
    done
    packed=$(find .fuzzkit/stage/build/fuzz -type f | wc -l)
    if [ -n "$targets" ] && [ "$packed" -ne "$(tr , '\n' <<<"$targets" | grep -c .)" ]; then
      echo "fuzz_kit.sh: $targets names a target that tests/fuzz does not have ($packed packed)" >&2
      exit 1
    fi
    tar -C .fuzzkit/stage -cJf .fuzzkit/kit.tar.xz build lib
    rm -rf .fuzzkit/stage
    ls -la .fuzzkit/kit.tar.xz
    ;;
  unpack)
    [ -f .fuzzkit/kit.tar.xz ] || { echo "fuzz_kit.sh: no .fuzzkit/kit.tar.xz (carry it)" >&2; exit 1; }
    tar -C .fuzzkit -xJf .fuzzkit/kit.tar.xz
    ;;
  *) sed -n 2,12p "$0"; exit 2 ;;
esac
