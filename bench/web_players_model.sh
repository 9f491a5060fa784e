#!/usr/bin/env bash
# A trained model in the third-party players (issue 21 item 4): Babylon.js, PlayCanvas and
# three.js + Spark in headless Chromium (SwiftShader), against our render of the same camera and
# time and against the ground truth. The figures of BENCHMARKS.md's "A trained Panoptic model in
# the players".
#
#   bench/web_players_model.sh MODEL DATA [VIEWS] [OUT_DIR]
#
# MODEL: an .atex (untextured or textured; the players show its Gaussians without textures);
# DATA: its dataset (atex opens it by path); VIEWS: comma-separated test-view indices (default 0;
# pick views at different times); OUT_DIR (default out/web_players_model) receives the fixture
# (OUT_DIR/fixture: exports, references, pictures) and each player's JSON rows and log.
# Builds atex_web_fixture in build/ (configured), writes the scenes player_model_vN with
# ATEX_PLAYER_MODEL*, then runs only those scenes:
#   babylon     Babylon.js, .glb, its default blur and the 3DGS blur (viewer.mjs ?kernel=1.2)
#   playcanvas  PlayCanvas, .glb and .ply, its defaults and ?kernel=3dgs
#   spark       Spark, .ply and .spz, with the 3DGS dilation (the web test's settings)
# "base colours clamped": PSNR against our render with each Gaussian's base colour (0.5 + C0 DC)
# clamped to [0, 1], as players holding 8-bit colours show it (a diagnostic of the gap).
# ATEX_PLAYERS (e.g. babylon,spark) runs only those players; the table shows every player whose
# JSON is in OUT_DIR (so a rerun of one player keeps the others' rows).
# ATEX_PLAYER_FORMATS (e.g. glb,spz) limits the formats of PlayCanvas and Spark. Failed checks
# are reported, not fatal (they are the web tests' bounds); the script fails when a player gave
# no result. Prints a markdown table. SwiftShader at 640x360 with 360k splats: about a minute per
# picture on the CPU machine.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
case ${1:-} in -h|--help|'') sed -n '2,/^set -e/{/^#/p}' "$0"; exit 0 ;; esac
model=$(realpath "$1")
data=$(realpath "$2")
views=${3:-0}
out=${4:-out/web_players_model}
fixture="$out/fixture"
mkdir -p "$fixture"
fixture=$(realpath "$fixture")

cmake --build build -j2 --target atex_web_fixture > "$out/build.log"
echo "== fixture (views $views)" >&2
start=$(date +%s)
ATEX_SOURCE_DIR=$PWD ATEX_PLAYER_MODEL=$model ATEX_PLAYER_MODEL_DATA=$data ATEX_PLAYER_MODEL_VIEWS=$views \
  build/tests/atex_web_fixture "$fixture" > "$out/fixture.log"
echo "fixture: $(( $(date +%s) - start )) s" >&2
names=$(node -e 'const m = require(process.argv[1]); console.log((m.player_model || []).map((s) => s.name).join(","))' \
  "$fixture/manifest.json")
with_kernel=$(echo "$names" | sed 's/\([^,]*\)/\1,\1_3dgs_kernel/g')

players=${ATEX_PLAYERS:-babylon,playcanvas,spark}
run() {  # PLAYER SCENES COMMAND...
  local player=$1 scenes=$2
  shift 2
  case ",$players," in *",$player,"*) ;; *) return 0 ;; esac
  echo "== $player ($scenes)" >&2
  rm -f "$fixture/${player}_results.json"
  ATEX_PLAYER_SCENES=$scenes "$@" > "$out/$player.log" 2>&1 || true
  [ -s "$fixture/${player}_results.json" ] || { echo "$player: no results (see $out/$player.log)" >&2; exit 1; }
  cp "$fixture/${player}_results.json" "$out/$player.json"
  grep '^FAIL' "$out/$player.log" >&2 || true
}
run babylon "$with_kernel" node tests/web/babylon_render.mjs "$fixture"
run playcanvas "$with_kernel" node tests/web/player_render.mjs playcanvas "$fixture"
run spark "$names" node tests/web/player_render.mjs spark "$fixture"

node - "$out" <<'EOF_NODE'
const fs = require('fs');
const out = process.argv[2];
const f = (x, d = 2) => (x === undefined ? '–' : x.toFixed(d));
const settings = (player, r) => {
  if (player === 'babylon') return r.kernel ? 'blur of 3DGS (?kernel=1.2)' : 'defaults';
  if (player === 'playcanvas') return r.settings && r.settings.kernel ? '?kernel=3dgs' : 'defaults';
  return r.settings && r.settings.spark ? `3DGS dilation (${r.settings.spark})` : 'defaults';
};
console.log('| player | settings | format | view (camera, time) | PSNR vs our render | vs ours, base colours clamped | PSNR vs truth | s |');
console.log('|---|---|---|---|---:|---:|---:|---:|');
for (const player of ['babylon', 'playcanvas', 'spark']) {
  if (!fs.existsSync(`${out}/${player}.json`)) continue;
  for (const r of JSON.parse(fs.readFileSync(`${out}/${player}.json`, 'utf8'))) {
    const name = player === 'babylon' ? 'Babylon.js' : r.player;  // the page's own name and version
    console.log(`| ${name} | ${settings(player, r)} | .${r.format} | ${r.scene.replace(/_3dgs_kernel$/, '')} (${r.view}, t = ${f(r.time, 3)}) | ` +
                `${f(r.psnr)} | ${f(r.psnrVsClamped)} | ${f(r.psnrVsTruth)} | ${f(r.seconds, 1)} |`);
  }
}
EOF_NODE
