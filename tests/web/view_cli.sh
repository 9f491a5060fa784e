#!/usr/bin/env bash
# `atex view` on the command line: the --json summary agrees with the page written, the
# payload's options (--frames, --max-splats, --max-mib, --up) take effect, a dataset camera
# opens the page, and bad command lines are refused before any work (exit 2) or fail
# (exit 1) without touching an existing output.
#   tests/web/view_cli.sh ATEX_BINARY SOURCE_DIR
set -euo pipefail
atex=$1
source_dir=$2
work=$(mktemp -d "${TMPDIR:-/tmp}/atex-view-XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
ok() { echo "ok   $*"; }
field() { python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); print(eval(sys.argv[2], {}, {"d": d}))' "$@"; }
lego="$source_dir/samples/lego_adaptive_2MiB.atex"
sample="$source_dir/samples/sample.atex"

help=$("$atex" view --help)
for word in --frames --max-splats --max-mib --data --force --json; do
  grep -q -- "$word" <<< "$help" || fail "view --help does not mention $word"
done
ok "view --help"

"$atex" view "$lego" -o "$work/a.html" --frames 3 --max-splats 5000 --json > "$work/a.json" 2> /dev/null
[ "$(field "$work/a.json" 'd["kept"]')" = 5000 ] || fail "--max-splats 5000: $(cat "$work/a.json")"
[ "$(field "$work/a.json" 'd["gaussians"]')" = 91490 ] || fail "gaussians: $(cat "$work/a.json")"
[ "$(field "$work/a.json" 'd["frames"]')" = 3 ] || fail "--frames 3: $(cat "$work/a.json")"
[ "$(field "$work/a.json" 'd["times"]')" = "[0.0, 0.5, 1.0]" ] || fail "keyframe times: $(cat "$work/a.json")"
[ "$(field "$work/a.json" 'd["up"]')" = "+z" ] || fail "the lego's up axis is +z (metadata.up): $(cat "$work/a.json")"
[ "$(field "$work/a.json" 'd["bytes"]')" = "$(wc -c < "$work/a.html")" ] || fail "summary bytes != file size"
grep -q 'id="atex-view-data"' "$work/a.html" || fail "no payload element in the page"
grep -q '<title>lego_adaptive_2MiB.atex</title>' "$work/a.html" || fail "the title is not the file name"
if grep -Eq '(src|href)="(https?:)?//' "$work/a.html"; then fail "the page refers to the network"; fi
ok "the summary matches the page (5000 Gaussians, 3 keyframes, +z up, no network references)"

# --no-compress: plain base64 arrays, larger, the same Gaussians.
"$atex" view "$lego" -o "$work/p.html" --frames 3 --max-splats 5000 --no-compress --json > "$work/p.json" 2> /dev/null
grep -q '"encoding":"raw"' "$work/p.html" || fail "--no-compress: no raw arrays"
grep -q '"encoding":"delta-planes-deflate"' "$work/a.html" || fail "the default page is not compressed"
[ "$(wc -c < "$work/p.html")" -gt "$(wc -c < "$work/a.html")" ] || fail "--no-compress is not larger"
[ "$(field "$work/p.json" 'd["payload_bytes"]')" = "$(field "$work/a.json" 'd["payload_bytes"]')" ] || fail "payload differs"
ok "--no-compress writes plain arrays ($(wc -c < "$work/p.html") vs $(wc -c < "$work/a.html") bytes)"

# --up turns the opening camera: the camera's up (-row 1 of world_to_camera) follows it.
"$atex" view "$sample" -o "$work/y.html" --up +y --json > "$work/y.json" 2> /dev/null
[ "$(field "$work/y.json" 'round(-d["camera"]["world_to_camera"][5], 3)')" = 0.94 ] || fail "--up +y: $(cat "$work/y.json")"
ok "--up +y opens with +y up (20 degrees of elevation)"

# The size cap drops keyframes, then refuses.
"$atex" view "$lego" -o "$work/c.html" --frames 20 --max-mib 8 --json > "$work/c.json" 2> /dev/null
frames=$(field "$work/c.json" 'd["frames"]')
[ "$frames" -lt 20 ] && [ "$frames" -ge 2 ] || fail "--max-mib 8 kept $frames keyframes"
[ "$(wc -c < "$work/c.html")" -le $((8 * 1048576)) ] || fail "--max-mib 8: the page is larger"
ok "--max-mib 8 keeps $frames of 20 keyframes"
set +e
"$atex" view "$lego" -o "$work/d.html" --max-mib 0.5 > /dev/null 2> "$work/d.err"; rc=$?
set -e
[ $rc = 1 ] && grep -q "max_splats\|cap" "$work/d.err" || fail "--max-mib 0.5: exit $rc, $(cat "$work/d.err")"
[ ! -e "$work/d.html" ] || fail "a refused page was written"
ok "a cap below two keyframes fails (exit 1) and writes nothing"

# Refusals.
expect() {  # expect EXIT_CODE DESCRIPTION ARGS...
  local want=$1 what=$2
  shift 2
  set +e
  "$atex" view "$@" > "$work/out" 2> "$work/err"
  local rc=$?
  set -e
  [ $rc = "$want" ] || fail "$what: exit $rc (expected $want): $(cat "$work/err")"
  ok "$what: exit $rc"
}
echo keep > "$work/keep.html"
expect 1 "an existing page without --force" "$sample" -o "$work/keep.html"
[ "$(cat "$work/keep.html")" = keep ] || fail "the existing page was replaced"
expect 0 "an existing page with --force" "$sample" -o "$work/keep.html" --force
expect 1 "an output that is not .html" "$sample" -o "$work/a.png"
expect 2 "--frames 1" "$sample" -o "$work/e.html" --frames 1
expect 2 "--frames x" "$sample" -o "$work/e.html" --frames x
expect 2 "--max-splats 0" "$sample" -o "$work/e.html" --max-splats 0
expect 2 "--up +w" "$sample" -o "$work/e.html" --up +w
expect 2 "--data with --size" "$sample" -o "$work/e.html" --data x --size 10x10
expect 2 "--size without intrinsics" "$sample" -o "$work/e.html" --size 10x10
expect 1 "a missing asset" "$work/missing.atex" -o "$work/e.html"
set +e
"$atex" view "$work/missing.atex" -o "$work/e.html" --json > "$work/err.json" 2> /dev/null
set -e
[ "$(field "$work/err.json" 'd["error"]["name"]')" = not-found ] || fail "--json error: $(cat "$work/err.json")"
ok "--json errors are JSON on stdout"

# A dataset camera opens the page (the lego's first test view).
data_dir=${ATEX_DATA_DIR:-$source_dir/../shared/data}
npz="$data_dir/dnerf_lego_tiny/tiny_dnerf_data.npz"
if [ -f "$npz" ]; then
  "$atex" view "$lego" -o "$work/v.html" --frames 2 --max-splats 1000 --data "$npz" --view test:0 --json > "$work/v.json" 2> /dev/null
  "$atex" render "$lego" --data "$npz" --view test:0 -o "$work/v.png" --backend cpu --json > "$work/r.json"
  [ "$(field "$work/v.json" 'd["camera"]["width"]')" = "$(field "$work/r.json" 'd["width"]')" ] || fail "--data camera size"
  ok "--data --view test:0 opens with the dataset's camera"
elif [ "${ATEX_REQUIRE_DATA:-0}" = 1 ]; then
  fail "real data missing: $npz"
else
  echo "skip the dataset camera check: $npz is missing"
fi
echo "all checks passed"
