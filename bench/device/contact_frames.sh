#!/usr/bin/env bash
# Renders every STEP-th frame of the given test cameras of MODEL next to their ground truth, for
# bench/contact_sheet.py (issue 20: is the fast ball there in every test frame?).
#   bench/device/contact_frames.sh MODEL EVAL_JSON OUT_DIR [CAMERAS=0,10] [STEP=3]
# EVAL_JSON is the model's `atex eval --json` (its "views" list is the order of test:N).
# Writes OUT_DIR/c<camera>_t<timestep>.png and ..._gt.png.
source "$(dirname "$0")/common.sh"
model=$1 eval_json=$2 dir=$3 cameras=${4:-0,10} step=${5:-3}
mkdir -p "$dir"
python3 - "$eval_json" "$cameras" "$step" <<'PY' | while read -r index camera timestep; do
import json, sys
views = json.load(open(sys.argv[1]))["views"]
cameras = {int(c) for c in sys.argv[2].split(",")}
step = int(sys.argv[3])
for i, v in enumerate(views):
    if v["camera"] in cameras and v["timestep"] % step == 0:
        print(i, v["camera"], v["timestep"])
PY
  "$atex" render "$model" --data "$bb" --view "test:$index" -o "$dir/c${camera}_t${timestep}.png" \
    --ground-truth "$dir/c${camera}_t${timestep}_gt.png" > /dev/null
done
ls "$dir" | wc -l
