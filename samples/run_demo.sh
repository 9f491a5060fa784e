#!/usr/bin/env bash
# The README's main job: the toolkit end to end on the bundled samples.
#
#   samples/run_demo.sh ATEX_BINARY [OUT_DIR]
#
# samples/lego_adaptive_2MiB.atex is a real trained asset (the tiny D-NeRF lego,
# trained on a GPU with the command in samples/README.md). The demo inspects and
# verifies it, renders and evaluates it against the real images when ../shared/data
# is present, exports it (glTF with KHR_gaussian_splatting, splaTV, per-frame PLY/SPZ,
# an OpenEXR texel atlas), fits it to a 1 MiB budget and prints the fitter's report,
# and re-packs the synthetic container sample with several codecs.
# With a CUDA GPU (and ATEX_DEMO_TRAIN=1) it first trains a fresh lego asset.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ATEX=${1:?usage: samples/run_demo.sh ATEX_BINARY [OUT_DIR]}
OUT=${2:-$(mktemp -d "${TMPDIR:-/tmp}/atex-demo.XXXXXX")}
mkdir -p "$OUT"
DATA=${ATEX_DATA_DIR:-$HERE/../../shared/data}
LEGO_DATA=$DATA/dnerf_lego_tiny/tiny_dnerf_data.npz
SAMPLE=$HERE/lego_adaptive_2MiB.atex

step() { echo; echo "== $*"; }

if [ "${ATEX_DEMO_TRAIN:-0}" = 1 ] && [ -f "$LEGO_DATA" ]; then
  step "atex train: both stages on the tiny lego (GPU when present; see samples/README.md)"
  "$ATEX" train --data "$LEGO_DATA" --out "$OUT/lego_trained.atex" --force --time-limit 600 \
    --set stage1.init_points=20000 --set stage1.fine_iterations=8000 \
    --set stage1.deformation.grid.channels=16 --set 'stage1.deformation.grid.base_resolution=[32,32,32,13]' \
    --set stage2.iterations=2000
  SAMPLE=$OUT/lego_trained.atex
fi

step "atex info: what the sample holds (Gaussians, texture-size histogram, deformation, chunks)"
"$ATEX" info "$SAMPLE"

step "atex verify: structure, every checksum and every value"
"$ATEX" verify "$SAMPLE"

if [ -f "$LEGO_DATA" ]; then
  step "atex render + eval against the real lego test images (CPU reference renderer without a GPU)"
  "$ATEX" render "$SAMPLE" --data "$LEGO_DATA" --view test:0 --out "$OUT/lego_test0.png" \
    --ground-truth "$OUT/lego_test0_truth.png" --force
  "$ATEX" eval "$SAMPLE" --data "$LEGO_DATA"
else
  step "skipping render/eval: $LEGO_DATA not found (set ATEX_DATA_DIR)"
fi

step "atex export: glTF 2.0 with KHR_gaussian_splatting + ATEX extensions, and splaTV"
"$ATEX" export "$SAMPLE" "$OUT/lego.glb" --force
"$ATEX" export "$SAMPLE" "$OUT/lego.splatv" --force
echo "open them in a browser: tests/web/install.sh; node tests/web/serve.mjs --data $OUT; then"
echo "  http://127.0.0.1:8080/?src=/data/lego.glb (Babylon.js) and http://127.0.0.1:8080/splatv.html?src=/data/lego.splatv"
step "atex view: one self-contained page that plays the sample in any browser (no server)"
"$ATEX" view "$SAMPLE" -o "$OUT/lego.html" --force
echo "open it: file://$OUT/lego.html"
step "atex convert: 3DGS PLY at t=0.5, per-frame SPZ, and the OpenEXR texel atlas"
"$ATEX" convert "$SAMPLE" "$OUT/lego_t0.5.ply" --time 0.5 --force
"$ATEX" convert "$SAMPLE" "$OUT/frames" --frames 0:1:0.25 --to spz --force
"$ATEX" convert "$SAMPLE" "$OUT/lego_texels.exr" --force || echo "(no OpenEXR in this build)"

step "atex fit: the sample to a 1 MiB budget (never over); the report says what each lever removed"
FIT_DATA=()
[ -f "$LEGO_DATA" ] && FIT_DATA=(--data "$LEGO_DATA")
"$ATEX" fit "$SAMPLE" "$OUT/lego_1MiB.atex" --force --budget 1MiB "${FIT_DATA[@]}"
"$ATEX" verify "$OUT/lego_1MiB.atex"
ls -l "$OUT/lego_1MiB.atex"

# The container's codecs on the synthetic sample.
PACKS=(
  "zstd19|--codec shuffle-zstd --level 19"
  "compact|--codec delta-shuffle-zstd --positions q16 --sh q8 --texels q8 --level 19"
  "raw|--codec raw"
)
for pack in "${PACKS[@]}"; do
  label=${pack%%|*}
  read -r -a options <<<"${pack#*|}"
  step "atex pack sample -> $label (${options[*]})"
  "$ATEX" pack "$HERE/sample.atex" "$OUT/sample.$label.atex" --force "${options[@]}"
  "$ATEX" verify "$OUT/sample.$label.atex"
done

step "done: outputs are in $OUT"
