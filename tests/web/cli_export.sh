#!/usr/bin/env bash
# `atex export` / `atex import` end to end on the fixture's moving.atex (textures + motion):
# every glTF form imports back losslessly (re-export is byte-identical), .splatv reports its
# fit, --frames writes the sequence, bad outputs fail with exit status 1.
#   tests/web/cli_export.sh ATEX_BINARY FIXTURE_DIR
set -euo pipefail
atex=$1
fixture=$2
work=$(mktemp -d "${TMPDIR:-/tmp}/atex-cli-XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
ok() { echo "ok   $*"; }
scene="$fixture/moving.atex"
[ -f "$scene" ] || fail "$scene is missing (the web_fixture test writes it)"

"$atex" export "$scene" "$work/a.glb" --json > "$work/a.json"
grep -q '"format": "glb"' "$work/a.json" || fail "export --json summary: $(cat "$work/a.json")"
"$atex" import "$work/a.glb" "$work/a.atex" > /dev/null
"$atex" export "$work/a.atex" "$work/b.glb" > /dev/null
cmp -s "$work/a.glb" "$work/b.glb" || fail ".glb -> .atex -> .glb is not byte-identical"
ok ".glb import is lossless (re-export byte-identical)"

"$atex" export "$scene" "$work/t.gltf" > /dev/null
[ -f "$work/t.bin" ] || fail ".gltf export wrote no t.bin"
"$atex" import "$work/t.gltf" "$work/t.atex" > /dev/null
"$atex" export "$work/t.atex" "$work/t.glb" > /dev/null
cmp -s "$work/a.glb" "$work/t.glb" || fail ".gltf + .bin import is not lossless"
ok ".gltf + .bin import is lossless"

"$atex" export "$scene" "$work/m.glb" --meshopt > /dev/null
"$atex" import "$work/m.glb" "$work/m.atex" > /dev/null
"$atex" export "$work/m.atex" "$work/m2.glb" > /dev/null
cmp -s "$work/a.glb" "$work/m2.glb" || fail "meshopt (exact floats + raw parameters) import is not lossless"
[ "$(stat -c %s "$work/m.glb")" -lt "$(stat -c %s "$work/a.glb")" ] || fail "meshopt output is not smaller"
"$atex" export "$scene" "$work/q.glb" --meshopt --meshopt-bits 12 --no-raw > /dev/null
[ "$(stat -c %s "$work/q.glb")" -lt "$(stat -c %s "$work/m.glb")" ] || fail "lossy meshopt output is not smaller"
ok "meshopt exports (exact: lossless; 12-bit: smaller)"

"$atex" export "$scene" "$work/z.glb" --spz > /dev/null
"$atex" import "$work/z.glb" "$work/z.atex" --json > "$work/z.json"
grep -q "\"gaussians\": $("$atex" info "$scene" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["gaussians"])')" \
  "$work/z.json" || fail "--spz import lost Gaussians: $(cat "$work/z.json")"
[ "$(stat -c %s "$work/z.glb")" -lt "$(stat -c %s "$work/q.glb")" ] || fail "--spz output is not smaller than lossy meshopt"
if "$atex" export "$scene" "$work/zm.glb" --spz --meshopt > /dev/null 2>&1; then fail "--spz --meshopt was accepted"; fi
ok "SPZ-in-glTF export (imports with every Gaussian, smaller than meshopt; not with --meshopt)"

"$atex" export "$scene" "$work/k.glb" --quantize --json > "$work/k_export.json"
grep -q '"quantize": true' "$work/k_export.json" || fail "export --quantize summary: $(cat "$work/k_export.json")"
"$atex" import "$work/k.glb" "$work/k.atex" --json > "$work/k.json"
grep -q "\"gaussians\": $("$atex" info "$scene" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["gaussians"])')" \
  "$work/k.json" || fail "--quantize import lost Gaussians: $(cat "$work/k.json")"
[ "$(stat -c %s "$work/k.glb")" -lt "$(stat -c %s "$work/a.glb")" ] || fail "--quantize output is not smaller"
"$atex" export "$scene" "$work/km.glb" --quantize --meshopt > /dev/null
[ "$(stat -c %s "$work/km.glb")" -lt "$(stat -c %s "$work/k.glb")" ] || fail "--quantize --meshopt is not smaller than --quantize"
if "$atex" export "$scene" "$work/kz.glb" --quantize --spz > /dev/null 2>&1; then fail "--quantize --spz was accepted"; fi
ok "quantised export (imports with every Gaussian, smaller; with --meshopt smaller still; not with --spz)"
# --bake-textures (issue 21 item 5): the import holds the baked count the summary reports, and
# no texture pool; a --no-textures export imports back too (its metadata says texture_mode none).
"$atex" export "$scene" "$work/bk.glb" --time 0.5 --bake-textures --json > "$work/bk.json"
baked_count=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["bake"]["gaussians_out"])' "$work/bk.json")
"$atex" import "$work/bk.glb" "$work/bk.atex" > /dev/null
"$atex" info "$work/bk.atex" --json > "$work/bk_info.json"
python3 - "$work/bk_info.json" "$baked_count" <<'PY' || fail "--bake-textures import: $(cat "$work/bk_info.json")"
import json, sys
info = json.load(open(sys.argv[1]))
assert info["gaussians"] == int(sys.argv[2]), (info["gaussians"], sys.argv[2])
assert not (info.get("textures") or {}).get("present"), info.get("textures")
PY
"$atex" export "$scene" "$work/nt.glb" --time 0.5 --no-textures > /dev/null
"$atex" import "$work/nt.glb" "$work/nt.atex" > /dev/null || fail "a --no-textures export does not import back"
ok "--bake-textures round trip ($baked_count Gaussians, no textures); --no-textures imports back"

"$atex" export "$scene" "$work/s.splatv" --samples 16 --json > "$work/s.json"
grep -q '"position_rms_relative"' "$work/s.json" || fail ".splatv export reports no fit: $(cat "$work/s.json")"
ok ".splatv export reports its fit"

"$atex" export "$scene" "$work/frames" --frames 0:1:0.25 > /dev/null
[ "$(ls "$work/frames"/frame_*.glb | wc -l)" = 5 ] || fail "--frames 0:1:0.25 did not write 5 frames"
grep -q '"time": 0.75' "$work/frames/frames.json" || fail "frames.json lacks t = 0.75"
"$atex" export "$scene" "$work/baked.glb" --time 0.5 > /dev/null
cmp -s "$work/frames/frame_0002.glb" "$work/baked.glb" || fail "frame 2 differs from --time 0.5"
ok "--frames sequence and --time agree"

if "$atex" export "$scene" "$work/x.unknown" 2> "$work/err.txt"; then fail "unknown output extension accepted"; fi
grep -q 'does not end\|is not .glb' "$work/err.txt" || fail "unclear error: $(cat "$work/err.txt")"
if "$atex" import "$scene" "$work/y.atex" 2> /dev/null; then fail "importing a non-glTF file succeeded"; fi
ok "bad inputs fail with a message"
echo "all checks passed"
