#!/usr/bin/env bash
# Compact glTF against SPZ and SOG (issue 21 item 3): bytes per Gaussian of one model in every
# form, and the PSNR of each read back by libatex and rendered by its reference renderer,
# against the same render of the lossless (float) glTF. The figures of BENCHMARKS.md's
# "Quantised glTF" paragraph.
#
#   bench/gltf_compact.sh [ATEX] [ASSET] [DATASET] [OUT_DIR]
#
# ATEX (default build/bin/atex); ASSET (default samples/lego_adaptive_2MiB.atex); DATASET (default
# ../shared/data/dnerf_lego_tiny/tiny_dnerf_data.npz) gives the time of its test view 0, whose
# camera comes from build/web_fixture/player_lego_camera.json (`ctest -R web_fixture` writes it;
# or $ATEX_CAMERA_JSON); OUT_DIR (default out/gltf_compact). Every form holds the base attributes only
# (the Gaussians at that time, no textures, no deformation field, no raw parameters), as SPZ and
# SOG do. SOG is written by PlayCanvas splat-transform (tests/splat_transform, npm) from our PLY;
# without it that row is left out. Renders at the dataset camera (100x100 for the tiny lego) and
# at 4x its resolution (intrinsics x4), where the quantisation of sub-pixel splats shows.
# Prints a markdown table. The glTF rows carry COLOR_0 (4 bytes per Gaussian, the point-cloud
# fallback) unless their name says nocolor.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
case ${1:-} in -h|--help) sed -n 2,18p "$0"; exit 0 ;; esac
atex=$(realpath "${1:-build/bin/atex}")
asset=$(realpath "${2:-samples/lego_adaptive_2MiB.atex}")
data=$(realpath "${3:-../shared/data/dnerf_lego_tiny/tiny_dnerf_data.npz}")
out=${4:-out/gltf_compact}
mkdir -p "$out"
out=$(realpath "$out")
splat_transform=tests/splat_transform/node_modules/@playcanvas/splat-transform/bin/cli.mjs

# The view's time and camera (the dataset's test view 0), read back from a render's summary.
time=$("$atex" render "$asset" --data "$data" --view test:0 -o "$out/truth_view.png" -f --json |
       python3 -c 'import json,sys; print(json.load(sys.stdin)["time"])')
base=(--time "$time" --no-textures --no-raw)

forms=()  # NAME FILE (a reader of ours turns FILE into NAME.atex)
export_glb() {  # NAME OPTIONS...
  local name=$1
  shift
  "$atex" export "$asset" "$out/$name.glb" "${base[@]}" "$@" -f > /dev/null
  "$atex" import "$out/$name.glb" "$out/$name.atex" -f > /dev/null
  forms+=("$name" "$out/$name.glb")
}
export_glb gltf_float
export_glb gltf_quantize --quantize
export_glb gltf_quantize_meshopt --quantize --meshopt
export_glb gltf_quantize_meshopt_sh12 --quantize --meshopt --meshopt-bits 12
export_glb gltf_quantize_meshopt_sh12_nocolor --quantize --meshopt --meshopt-bits 12 --no-color
export_glb gltf_meshopt --meshopt
export_glb gltf_spz --spz
"$atex" convert "$asset" "$out/spz_v4.spz" --time "$time" -f > /dev/null
"$atex" convert "$out/spz_v4.spz" "$out/spz_v4.atex" -f > /dev/null
forms+=(spz_v4 "$out/spz_v4.spz")
if [ -f "$splat_transform" ]; then
  "$atex" convert "$asset" "$out/lego.ply" --time "$time" -f > /dev/null
  rm -f "$out/sog.sog"
  node "$splat_transform" "$out/lego.ply" "$out/sog.sog" > "$out/splat_transform.log" 2>&1
  "$atex" convert "$out/sog.sog" "$out/sog.atex" -f > /dev/null
  forms+=(sog "$out/sog.sog")
else
  echo "SOG left out: run tests/splat_transform/install.sh" >&2
fi

# Renders: the dataset's test view 0 camera (from the web fixture's camera file: intrinsics and the
# row-major OpenCV world-to-camera that atex_web_fixture writes for the same view) at 1x and at 4x
# (intrinsics x4). SPZ and PLY (hence SOG) hold the world turned so that the asset's up axis is
# their up (convert/world_turn.h: 180 degrees about x after glTF's turn to +Y), and our readers do
# not turn it back, so their renders use the camera turned the same way (pose . R^T). A wrong turn
# shows as a PSNR near 12 dB.
camera_json=${ATEX_CAMERA_JSON:-build/web_fixture/player_lego_camera.json}
[ -f "$camera_json" ] || { echo "no camera file $camera_json (run ctest -R web_fixture or set ATEX_CAMERA_JSON)" >&2; exit 1; }
up=$("$atex" info "$asset" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["metadata"].get("up", "-y"))')
cameras=$(python3 - "$camera_json" "$up" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
w = c["pose"]["opencv_world_to_camera"]
# UpRotationMatrix (gltf.h): the proper rotation taking `up` to +Y; then 180 degrees about x.
to_y = {"+y": [1, 0, 0, 0, 1, 0, 0, 0, 1], "-y": [1, 0, 0, 0, -1, 0, 0, 0, -1],
        "+z": [1, 0, 0, 0, 0, 1, 0, -1, 0], "-z": [1, 0, 0, 0, 0, -1, 0, 1, 0],
        "+x": [0, -1, 0, 1, 0, 0, 0, 0, 1], "-x": [0, 1, 0, -1, 0, 0, 0, 0, 1]}[sys.argv[2]]
flip = [1, 0, 0, 0, -1, 0, 0, 0, -1]
r = [sum(flip[i * 3 + k] * to_y[k * 3 + j] for k in range(3)) for i in range(3) for j in range(3)]
turned = list(w)
for row in range(4):
    for col in range(3):  # (W . diag(R^T, 1))[row][col] = sum_k W[row][k] R[col][k]
        turned[row * 4 + col] = sum(w[row * 4 + k] * r[col * 3 + k] for k in range(3))
k = [c["fx"], c["fy"], c["cx"], c["cy"]]
print(c["width"], c["height"], *k, *w)
print(c["width"], c["height"], *k, *turned)
PY
)
read -r -a plain_cam <<< "$(sed -n 1p <<< "$cameras")"
read -r -a turned_cam <<< "$(sed -n 2p <<< "$cameras")"
render_all() {  # NAME plain|turned -> NAME_1x.png NAME_4x.png
  local name=$1 cam
  if [ "$2" = turned ]; then cam=("${turned_cam[@]}"); else cam=("${plain_cam[@]}"); fi
  local w=${cam[0]} h=${cam[1]} fx=${cam[2]} fy=${cam[3]} cx=${cam[4]} cy=${cam[5]}
  "$atex" render "$out/$name.atex" --size "${w}x${h}" --intrinsics "$fx" "$fy" "$cx" "$cy" \
    --world-to-camera "${cam[@]:6:16}" -o "$out/${name}_1x.png" -f > /dev/null
  local k4
  read -r -a k4 <<< "$(python3 -c "print(4 * $fx, 4 * $fy, 4 * $cx, 4 * $cy)")"
  "$atex" render "$out/$name.atex" --size "$((4 * w))x$((4 * h))" --intrinsics "${k4[@]}" \
    --world-to-camera "${cam[@]:6:16}" -o "$out/${name}_4x.png" -f > /dev/null
}
for ((i = 0; i < ${#forms[@]}; i += 2)); do
  case ${forms[i]} in spz_v4|sog) render_all "${forms[i]}" turned ;; *) render_all "${forms[i]}" plain ;; esac
done

python3 - "$out" "$("$atex" info "$asset" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["gaussians"])')" "${forms[@]}" <<'EOF'
import os, struct, sys, zlib, math

def read_png(path):
    """8-bit RGB/RGBA PNG -> (width, height, channels, bytes); a minimal reader (no numpy here)."""
    data = open(path, 'rb').read()
    assert data[:8] == b'\x89PNG\r\n\x1a\n', path
    pos, idat, w = 8, b'', 0
    while pos < len(data):
        length, kind = struct.unpack('>I4s', data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b'IHDR':
            w, h, depth, ctype = struct.unpack('>IIBB', body[:10])
            assert depth == 8 and ctype in (2, 6), (path, depth, ctype)
            ch = 3 if ctype == 2 else 4
        elif kind == b'IDAT':
            idat += body
        pos += 12 + length
    raw, stride, out, prev = zlib.decompress(idat), w * ch, bytearray(), bytearray(w * ch)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - ch] if x >= ch else 0
            b, c = prev[x], prev[x - ch] if x >= ch else 0
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out += line
        prev = line
    return w, h, ch, out

def psnr(a_path, b_path):
    wa, ha, ca, a = read_png(a_path)
    wb, hb, cb, b = read_png(b_path)
    assert (wa, ha) == (wb, hb)
    se = sum((a[i * ca + c] - b[i * cb + c]) ** 2 for i in range(wa * ha) for c in range(3))
    mse = se / (wa * ha * 3 * 255.0 ** 2)
    return float('inf') if mse == 0 else -10 * math.log10(mse)

out, n, forms = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
print(f'| form | bytes | bytes/Gaussian | PSNR vs float glTF, 1x | PSNR, 4x |')
print('|---|---:|---:|---:|---:|')
for name, path in zip(forms[0::2], forms[1::2]):
    size = os.path.getsize(path)
    cells = []
    for scale in ('1x', '4x'):
        p = psnr(os.path.join(out, f'{name}_{scale}.png'), os.path.join(out, f'gltf_float_{scale}.png'))
        cells.append('exact' if p == float('inf') else f'{p:.2f}')
    print(f'| {name} | {size:,} | {size / n:.2f} | {cells[0]} | {cells[1]} |')
EOF
