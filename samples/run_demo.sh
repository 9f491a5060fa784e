#!/usr/bin/env bash
# The toolkit on the bundled sample: inspect, verify and re-pack it.
#
#   samples/run_demo.sh ATEX_BINARY [OUT_DIR]
#
# ASSETS lists the sample files and PACKS the re-encodings to try; add entries to
# extend the demo (a trained asset, a render, an export, ...).
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ATEX=${1:?usage: samples/run_demo.sh ATEX_BINARY [OUT_DIR]}
OUT=${2:-$(mktemp -d "${TMPDIR:-/tmp}/atex-demo.XXXXXX")}
mkdir -p "$OUT"

ASSETS=("$HERE/sample.atex")
# name|options for `atex pack`
# (encodings not named keep the sample's own: see `atex pack --help`)
PACKS=(
  "zstd19|--codec shuffle-zstd --level 19"
  "compact|--codec delta-shuffle-zstd --positions q16 --sh q8 --texels q8 --level 19"
  "exact-f32|--codec shuffle-zstd --positions f32 --sh f32 --texels f32"
  "raw|--codec raw"
)

step() { echo; echo "== $*"; }

for asset in "${ASSETS[@]}"; do
  name=$(basename "$asset" .atex)
  step "atex info $name: what the file holds (counts, textures, deformation, chunks, bytes per component)"
  "$ATEX" info "$asset"

  step "atex verify $name: structure, every checksum and every value"
  "$ATEX" verify "$asset"

  for pack in "${PACKS[@]}"; do
    label=${pack%%|*}
    read -r -a options <<<"${pack#*|}"
    out="$OUT/$name.$label.atex"
    step "atex pack $name -> $label (${options[*]})"
    "$ATEX" pack "$asset" "$out" "${options[@]}"
    "$ATEX" verify "$out"
  done
done

step "done: the packed files are in $OUT"
