#!/usr/bin/env bash
# Texture baking for KHR-only players (issue 21 item 5), measured with libatex's CPU renderer.
#
#   bench/texture_bake.sh [ATEX] [ASSET] [DATASET] [OUT] [VIEWS]
#
# For each of the dataset's first VIEWS test views (default 5), at the view's time:
#   textured  `atex render` of the asset (textures included: what our players show)
#   plain     `atex export --time T --no-textures` -> `atex import` -> render: what a
#             KHR_gaussian_splatting player can show today (the texture is dropped)
#   baked     `atex export --time T --bake-textures` -> `atex import` -> render
# and prints the PSNR of plain and baked against the textured render and the ground truth, the
# .glb sizes (default export with ATEX_gaussian_textures, plain, baked) and the bake report.
# Defaults: build/bin/atex, the bundled lego sample, ../shared/data/dnerf_lego_tiny.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
atex=${1:-build/bin/atex}
asset=${2:-samples/lego_adaptive_2MiB.atex}
data=${3:-../shared/data/dnerf_lego_tiny/tiny_dnerf_data.npz}
out=${4:-build/texture_bake_bench}
views=${5:-5}
mkdir -p "$out"
psnr() { python3 "$here/png_psnr.py" "$1" "$2" | cut -d' ' -f1; }
printf '%-5s %-6s %8s %8s %8s %8s %8s %10s %10s %10s %s\n' view time tex/gt plain/tex baked/tex plain/gt baked/gt \
  glb_tex glb_plain glb_baked gaussians
for ((i = 0; i < views; ++i)); do
  time=$("$atex" render "$asset" --data "$data" --view "test:$i" -o "$out/textured_$i.png" \
           --ground-truth "$out/truth_$i.png" -f --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["time"])')
  "$atex" export "$asset" "$out/textured_$i.glb" --time "$time" -f >/dev/null
  "$atex" export "$asset" "$out/plain_$i.glb" --time "$time" --no-textures -f >/dev/null
  "$atex" export "$asset" "$out/baked_$i.glb" --time "$time" --bake-textures -f --json >"$out/baked_$i.json"
  for kind in plain baked; do
    "$atex" import "$out/${kind}_$i.glb" "$out/${kind}_$i.atex" -f >/dev/null
    "$atex" render "$out/${kind}_$i.atex" --data "$data" --view "test:$i" --time "$time" -o "$out/${kind}_$i.png" -f \
      >/dev/null
  done
  gaussians=$(python3 -c '
import json, sys
b = json.load(open(sys.argv[1]))["bake"]
print("%d->%d (split %d, folded %d, fit rms %.4f vs %.4f unbaked)" % (b["gaussians_in"], b["gaussians_out"], b["split"],
      b["folded"], b["fit_rms"], b["fit_rms_unbaked"]))' "$out/baked_$i.json")
  printf '%-5s %-6s %8s %8s %8s %8s %8s %10s %10s %10s %s\n' "$i" "$time" \
    "$(psnr "$out/truth_$i.png" "$out/textured_$i.png")" \
    "$(psnr "$out/textured_$i.png" "$out/plain_$i.png")" "$(psnr "$out/textured_$i.png" "$out/baked_$i.png")" \
    "$(psnr "$out/truth_$i.png" "$out/plain_$i.png")" "$(psnr "$out/truth_$i.png" "$out/baked_$i.png")" \
    "$(stat -c %s "$out/textured_$i.glb")" "$(stat -c %s "$out/plain_$i.glb")" "$(stat -c %s "$out/baked_$i.glb")" \
    "$gaussians"
done
