#!/usr/bin/env bash
# Third-party players on our exports (issue 21 item 4): the figures of BENCHMARKS.md's
# "Players" paragraph, from tests/web/player_render.mjs in headless Chromium (SwiftShader).
#
#   bench/web_players.sh [FIXTURE_DIR] [OUT_DIR]
#
# FIXTURE_DIR (default build/web_fixture) is written by `ctest -R "web_fixture|web_babylon_render"`
# (the Babylon.js run leaves its lego picture there, player_lego_browser.png). Runs:
#   playcanvas          PlayCanvas with its defaults (.glb, .ply)          = the web test
#   spark_3dgs          Spark with the 3DGS dilation (.ply, .spz)          = the web test
#   spark_defaults      Spark with its own defaults (Mip-Splatting's compensated blur)
#   spark_0.075_vs_babylon / _vs_playcanvas   Spark with a 0.075 px^2 dilation, compared with
#                       Babylon's and PlayCanvas's pictures instead of ours
#   spark_0.3_vs_babylon / _vs_playcanvas     the same with the 3DGS 0.3 px^2
#   playcanvas_3dgs     PlayCanvas with the page's ?kernel=3dgs (samples/web/playcanvas_3dgs.mjs)
#                       on the lego (.glb, .ply; = the web test's kernel scene) and the F
#   playcanvas_PARTS    the lego (.glb) with only some of its parts: dilation, falloff,
#                       dilation+falloff, falloff+extent
# Checks that fail in the experiments are expected (they are the tests' bounds, not these
# settings'); the script fails only when a run produced no result. Prints a markdown table;
# OUT_DIR (default out/web_players) keeps each run's JSON rows and lego pictures, and a strip
# of the lego pictures (ours, Babylon.js, PlayCanvas, PlayCanvas 3DGS, Spark 3DGS, Spark
# defaults) when ffmpeg is there.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
case ${1:-} in -h|--help) sed -n 2,23p "$0"; exit 0 ;; esac
fixture=$(realpath "${1:-build/web_fixture}")
out=${2:-out/web_players}
mkdir -p "$out"
[ -f "$fixture/manifest.json" ] || { echo "no fixture in $fixture: run ctest -R web_fixture" >&2; exit 1; }

run() {  # NAME PLAYER FORMATS SCENES QUERY REFERENCE
  local name=$1 player=$2
  echo "== $name" >&2
  rm -f "$fixture/${player}"_player_lego_*.png "$fixture/${player}_results.json"
  ATEX_PLAYER_FORMATS=$3 ATEX_PLAYER_SCENES=$4 ATEX_PLAYER_QUERY=$5 ATEX_PLAYER_REFERENCE=$6 \
    node tests/web/player_render.mjs "$player" "$fixture" > "$out/$name.log" 2>&1 || true
  [ -s "$fixture/${player}_results.json" ] || { echo "$name: no results (see $out/$name.log)" >&2; exit 1; }
  cp "$fixture/${player}_results.json" "$out/$name.json"
  rm "$fixture/${player}_results.json"
  for f in "$fixture/${player}"_player_lego_*.png; do
    [ -f "$f" ] || continue
    case $f in *_vs_atex.png) continue ;; esac
    cp "$f" "$out/${name}_$(basename "$f")"
  done
}
run playcanvas playcanvas glb,ply letter_f,player_lego "" ""
run spark_defaults spark ply,spz letter_f,player_lego 'spark={}' ""
blur() { printf 'spark={"preBlurAmount":%s,"blurAmount":0}' "$1"; }
for b in 0.075 0.3; do
  if [ -f "$fixture/player_lego_browser.png" ]; then
    run "spark_${b}_vs_babylon" spark spz player_lego "$(blur "$b")" player_lego_browser.png
  fi
  run "spark_${b}_vs_playcanvas" spark spz player_lego "$(blur "$b")" playcanvas_player_lego_glb.png
done
run spark_3dgs spark ply,spz letter_f,player_lego "" ""
# (after the Spark runs: these overwrite PlayCanvas's lego picture in the fixture)
run playcanvas_3dgs playcanvas glb,ply player_lego_3dgs_kernel "" ""
run playcanvas_3dgs_letter_f playcanvas glb,ply letter_f kernel=3dgs ""
for parts in dilation falloff dilation,falloff falloff,extent; do
  run "playcanvas_${parts/,/+}" playcanvas glb player_lego "kernel=$parts" ""
done

node - "$out" <<'EOF_NODE'
const fs = require('fs');
const out = process.argv[2];
const f = (x, d = 2) => (x === undefined ? '–' : x.toFixed(d));
console.log('| run | player | scene | file | IoU (R/G/B) | upside down / mirrored IoU | PSNR | vs textured | vs truth | s |');
console.log('|---|---|---|---|---|---|---:|---:|---:|---:|');
for (const file of fs.readdirSync(out).filter((n) => n.endsWith('.json')).sort()) {
  for (const r of JSON.parse(fs.readFileSync(`${out}/${file}`, 'utf8'))) {
    console.log(`| ${file.replace('.json', '')} | ${r.player} | ${r.scene} | .${r.format} | ${f(r.iou, 3)} (${f(r.iouRed, 3)}/${f(r.iouGreen, 3)}/${f(r.iouBlue, 3)}) | ${f(r.iouUpsideDown, 3)} / ${f(r.iouMirrored, 3)} | ${f(r.psnr)} | ${f(r.psnrVsAtexTextured)} | ${f(r.psnrVsTruth)} | ${f(r.seconds, 1)} |`);
  }
}
EOF_NODE

# The lego pictures side by side (ours untextured, Babylon.js, PlayCanvas, PlayCanvas with
# ?kernel=3dgs, Spark 3DGS, Spark defaults).
if command -v ffmpeg > /dev/null 2>&1 && [ -f "$fixture/player_lego_browser.png" ]; then
  ffmpeg -loglevel error -y -i "$fixture/player_lego_untextured.png" -i "$fixture/player_lego_browser.png" \
    -i "$out/playcanvas_playcanvas_player_lego_glb.png" \
    -i "$out/playcanvas_3dgs_playcanvas_player_lego_3dgs_kernel_glb.png" \
    -i "$out/spark_3dgs_spark_player_lego_spz.png" -i "$out/spark_defaults_spark_player_lego_spz.png" \
    -filter_complex "hstack=inputs=6,scale=iw*2:ih*2:flags=neighbor" "$out/players_lego_strip.png"
  echo "strip: $out/players_lego_strip.png" >&2
fi
