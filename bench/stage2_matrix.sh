#!/usr/bin/env bash
# Stage-2 variants from ONE stage-1 model, paired as in the paper (same model, seed and
# camera schedule): uniform 4x4, adaptive, and the three ablations; each is trained,
# evaluated on the test views and timed at 640x360 and 1352x1014. The stage-1 model
# itself is the "none" (plain 4DGS) row.
#   bench/stage2_matrix.sh ATEX_BINARY DATA STAGE1.atex OUT_DIR [extra atex-train options...]
set -euo pipefail
atex=$1 data=$2 stage1=$3 out=$4
shift 4
mkdir -p "$out"
fps() {  # asset name
  for size in 640x360 1352x1014; do
    "$atex" fps "$1" --data "$data" --size "$size" --json > "$out/$2.fps.$size.json"
  done
}
"$atex" eval "$stage1" --data "$data" --json > "$out/none.eval.json"
fps "$stage1" none
for variant in uniform adaptive no-temporal-peak no-anisotropic no-visibility-normalization; do
  args=(--textures adaptive)
  case $variant in
    uniform) args=(--textures uniform) ;;
    no-temporal-peak) args+=(--set stage2.ablations.temporal_peak=false) ;;
    no-anisotropic) args+=(--set stage2.ablations.anisotropic=false) ;;
    no-visibility-normalization) args+=(--set stage2.ablations.visibility_normalization=false) ;;
  esac
  "$atex" train --data "$data" --stage 2 --init "$stage1" --out "$out/$variant.atex" "${args[@]}" "$@" --json \
    > "$out/$variant.json" 2> "$out/$variant.log"
  "$atex" info "$out/$variant.atex" --json > "$out/$variant.info.json"
  fps "$out/$variant.atex" "$variant"
  echo "$variant done" >&2
done
