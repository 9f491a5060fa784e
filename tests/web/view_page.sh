#!/usr/bin/env bash
# `atex view` end to end on the bundled lego sample: writes the page (default keyframes and
# opening camera), renders libatex's reference pictures of that camera at three times (the
# first keyframe, a time between two keyframes, the last keyframe) with `atex render`, then
# opens the page in headless Chromium (view_page.mjs) and compares. The page, the summary,
# the references and the side-by-side pictures stay in OUT_DIR.
#   tests/web/view_page.sh ATEX_BINARY SOURCE_DIR OUT_DIR [ASSET (default: the lego sample)]
set -euo pipefail
atex=$1
source_dir=$2
out=$3
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
sample=${4:-$source_dir/samples/lego_adaptive_2MiB.atex}
"$atex" view "$sample" -o "$out/view.html" --force --json > "$out/view.json" 2> "$out/view.log"
# The opening camera and the time range, from the summary.
# Compared at half the camera's size (the page's #scale=0.5: size and intrinsics halved) to
# keep software WebGL quick.
scale=0.5
read -r size intrinsics w2c t0 t1 < <(python3 - "$out/view.json" "$scale" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
c = d["camera"]
s = float(sys.argv[2])
print(f'{round(c["width"] * s)}x{round(c["height"] * s)}', ",".join(str(c[k] * s) for k in ("fx", "fy", "cx", "cy")),
      ",".join(repr(v) for v in c["world_to_camera"]), d["times"][0], d["times"][-1])
PY
)
frames=$(python3 -c 'import json,sys; print(len(json.load(open(sys.argv[1]))["times"]))' "$out/view.json")
# Between keyframes 12 and 13 of 25 (0.52 = 13/25, not a keyframe time k/24).
mid=$(python3 -c "print($t0 + 0.52 * ($t1 - $t0))")
refs="["
for t in "$t0" "$mid" "$t1"; do
  png="reference_t$t.png"
  "$atex" render "$sample" --backend cpu --size "$size" --intrinsics ${intrinsics//,/ } \
    --world-to-camera ${w2c//,/ } --time "$t" -o "$out/$png" --force > /dev/null
  refs="$refs{\"time\": $t, \"png\": \"$png\"},"
done
echo "${refs%,}]" > "$out/references.json"
echo "$scale" > "$out/scale.txt"
echo "atex view: $(wc -c < "$out/view.html") bytes, $frames keyframes; references at $t0, $mid, $t1"
exec bash "$here/run_node.sh" "$here/view_page.mjs" "$out"
