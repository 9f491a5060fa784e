// Loads our .glb files in unmodified Babylon.js (npm @babylonjs/core + @babylonjs/loaders)
// in headless Debian Chromium (software WebGL2), driven by playwright-core, and compares
// the screenshot with libatex's reference renderer for the same camera:
//   letter_f  a red/green/blue "F" with a camera stated in glTF terms (+z, +y up): per-colour
//             foreground IoU checks position, upright orientation, no mirroring, colours;
//             the same metric against the upside-down screenshot must be clearly worse
//   letter_f_meshopt  the same file with EXT_meshopt_compression (decoded by Babylon.js with
//             meshoptimizer's decoder from npm)
//   garden    real COLMAP points (gsplat's garden) under a real camera: foreground IoU and PSNR
//   splatv_player  our .splatv in samples/web/splatv.html (our WebGL2 player) at u = 0.5 against
//             the deformed scene rendered by libatex
//   player_lego  the bundled lego sample (a trained, textured 4D asset) baked at the time of the
//             dataset's first test view: PSNR against our render of its Gaussians without textures
//             (what a KHR_gaussian_splatting player can show; >= 20 dB with Babylon's default
//             blur), and reported against our textured render and the ground truth
//   player_lego_3dgs_kernel  the same with Babylon's blur set to 3DGS's (viewer.mjs ?kernel=1.2):
//             >= 35 dB, the issue's target
//   player_lego_quantized(_meshopt)  the same baked lego as `atex export --quantize` (KHR_mesh_quantization;
//             and with --meshopt) against Babylon's picture of the plain export (player_lego): >= 40 dB
//   player_model_vN(_3dgs_kernel)  an external trained model (bench/web_players_model.sh; the
//             fixture's optional ATEX_PLAYER_MODEL) at test view N's time and camera, with the same
//             two blurs: full-frame checks (common.mjs checkFullFrame): PSNR against our render >= 35
//             dB with the 3DGS kernel, reported only with the default blur; red/blue-swapped, upside
//             down and mirrored pictures must score clearly worse
//   upright   the bundled lego sample (Blender Z-up world): the up direction of its dataset's
//             cameras, carried through the splat mesh's world matrix (our node rotation and the
//             loader's handedness root), must point up (+y) in Babylon's world
// Side-by-side pictures (browser left, libatex right) are written as *_browser_vs_atex.png, the
// browser's picture alone as *_browser.png.
// ATEX_PLAYER_SCENES=a,b (experiments, bench/web_players_model.sh) draws only those scenes and
// skips the upright check.
// Usage: node babylon_render.mjs FIXTURE_DIR
import fs from 'node:fs';
import path from 'node:path';
import { compareInPage, newWatchedPage, openBrowser } from './browser.mjs';
import { check, checkFullFrame, checkOrientation, finish, readManifest } from './common.mjs';
import { startServer } from './serve.mjs';

// The quantised lego (--quantize) against Babylon's picture of the plain export. Babylon itself
// keeps rotations and colours in 8 bits and floats elsewhere; our 16-bit positions (steps of
// 1/65534 of the scene's extent, under 0.01 px at this view) and scales, 8-bit rotations (rounded
// again to Babylon's 8 bits) and 16-bit opacity change a few pixels by a grey level or two.
// Measured on the CPU machine (BENCHMARKS.md, "Quantised glTF"): 51.4 dB (--quantize) and 59.0 dB
// (with --meshopt: 16-bit rotations), IoU 0.999 and 1.000. A dequantisation 1 % off (the node's
// scale x 1.01, forged) gives 28.8 dB and IoU 0.980 and fails both checks; 0.1 % off gives 45.9 dB.
const THRESHOLD_QUANTIZED = 40;

const dir = path.resolve(process.argv[2] || '.');
const manifest = readManifest(dir);
// Issue 21 item 5, PSNR against our textured render: the baked lego may lose at most this much
// to the unbaked one; the baked textured tiles must gain at least this much.
const BAKE_TOLERANCE_DB = 0.2;
const TILES_MARGIN_DB = 2;
if (!manifest.garden && process.env.ATEX_REQUIRE_DATA === '1') {
  check(false, `real data for the garden scene is missing (${manifest.garden_missing})`);
}

const server = await startServer({ data: dir });
const started = Date.now();
const browser = await openBrowser();
const { context, offline } = browser;
const only = process.env.ATEX_PLAYER_SCENES;
const results = [];  // rows for babylon_results.json (bench/web_players_model.sh)
try {
  const scenes = [['letter_f', manifest.letter_f], ['letter_f_meshopt', manifest.letter_f_meshopt]];
  if (manifest.garden) scenes.push(['garden', manifest.garden]);
  if (manifest.player_lego) {
    scenes.push(['player_lego', manifest.player_lego]);
    // The same with Babylon's screen-space blur set to 3DGS's (viewer.mjs, ?kernel=).
    scenes.push(['player_lego_3dgs_kernel', { ...manifest.player_lego, kernel: 1.2 }]);
  }
  if (manifest.player_lego_quantized) {
    // `atex export --quantize` (and with --meshopt) against Babylon's picture of the plain export,
    // written by the player_lego scene above.
    const plain = { camera: manifest.player_lego.camera, reference: 'player_lego_browser.png',
                    untextured: manifest.player_lego.reference };
    scenes.push(['player_lego_quantized', { ...plain, glb: manifest.player_lego_quantized.glb }]);
    scenes.push(['player_lego_quantized_meshopt', { ...plain, glb: manifest.player_lego_quantized.glb_meshopt }]);
  }
  if (manifest.player_lego_baked) {
    // Issue 21 item 5: the textures baked into plain Gaussians (`atex export --bake-textures`).
    scenes.push(['player_lego_baked', manifest.player_lego_baked]);
    scenes.push(['player_lego_baked_3dgs_kernel', { ...manifest.player_lego_baked, kernel: 1.2 }]);
  }
  if (manifest.textured_tiles) {
    // Issue 21 item 5 on content whose textures matter: unbaked (Babylon drops the texture
    // extension) and baked, both against our textured render.
    scenes.push(['textured_tiles', { ...manifest.textured_tiles, kernel: 1.2 }]);
    scenes.push(['textured_tiles_baked', { ...manifest.textured_tiles, glb: manifest.textured_tiles.baked_glb, kernel: 1.2 }]);
  }
  const vsTextured = {};  // scene name -> PSNR against our textured render
  scenes.push(['splatv_player', manifest.splatv_view]);
  for (const model of manifest.player_model || []) {
    scenes.push([model.name, model]);
    scenes.push([`${model.name}_3dgs_kernel`, { ...model, kernel: 1.2 }]);
  }
  for (const [name, scene] of scenes.filter(([n]) => !only || only.split(',').includes(n))) {
    const camera = JSON.parse(fs.readFileSync(path.join(dir, scene.camera), 'utf8'));
    const { page, errors } = await newWatchedPage(context, camera.width, camera.height);
    const t0 = Date.now();
    await page.goto(scene.splatv ? `${server.url}/splatv.html?src=/data/${scene.splatv}&t=${scene.time}&fixed=1`
                                 : `${server.url}/index.html?src=/data/${scene.glb}&camera=/data/${scene.camera}` +
                                   (scene.kernel ? `&kernel=${scene.kernel}` : ''));
    let info;
    try {
      await page.waitForFunction(() => window.atexView !== undefined, null, { timeout: 60000 });
      info = await page.evaluate(() => window.atexView.ready);
    } catch (e) {
      check(false, `${name}: Babylon.js did not render: ${e.message} ${errors.join(' | ')}`);
      continue;
    }
    const stats = await page.evaluate(compareInPage, `/data/${scene.reference}`);
    fs.writeFileSync(path.join(dir, `${name}_browser_vs_atex.png`), Buffer.from(stats.sideBySidePng, 'base64'));
    fs.writeFileSync(path.join(dir, `${name}_browser.png`), Buffer.from(stats.playerPng, 'base64'));
    delete stats.sideBySidePng;
    delete stats.playerPng;
    if (scene.truth) {
      // A trained asset: also against our textured render and the ground truth (reported).
      stats.psnrVsAtexTextured = (await page.evaluate(compareInPage, `/data/${scene.atex}`)).psnr;
      stats.psnrVsTruth = (await page.evaluate(compareInPage, `/data/${scene.truth}`)).psnr;
      if (scene.clamped) {
        // Diagnostic: our render with each base colour clamped to [0, 1] (web_fixture_player.h).
        stats.psnrVsClamped = (await page.evaluate(compareInPage, `/data/${scene.clamped}`)).psnr;
      }
    }
    if (scene.truth) vsTextured[name] = stats.psnrVsAtexTextured;
    if (scene.untextured) {
      stats.psnrVsAtexUntextured = (await page.evaluate(compareInPage, `/data/${scene.untextured}`)).psnr;
      vsTextured[name] = stats.psnr;
    }
    const seconds = (Date.now() - t0) / 1000;
    console.log(`${name}: ${JSON.stringify({ ...info, ...stats, seconds })}`);
    results.push({ player: 'babylon', scene: name, format: 'glb', kernel: scene.kernel, view: scene.view,
                   time: scene.time, ...info, ...stats, seconds });
    check(errors.length === 0, `${name}: no page errors (${errors.slice(0, 3).join(' | ')})`);
    if (scene.splatv) {
      // Our own .splatv player (samples/web/splatv.html) at a fixed time, against libatex's
      // renderer of the deformed scene (DC colour only: splaTV has no view-dependent SH).
      check(stats.iou >= 0.95, `${name}: foreground IoU ${stats.iou.toFixed(3)} >= 0.95`);
      check(stats.psnr >= 35, `${name}: PSNR ${stats.psnr.toFixed(2)} dB >= 35 dB`);
      check(stats.iouUpsideDown < stats.iou - 0.1, `${name}: the upside-down picture matches worse (IoU ${stats.iouUpsideDown.toFixed(3)})`);
      await page.close();
      continue;
    }
    check(info.splatMeshes === 1, `${name}: Babylon built ${info.splatMeshes} Gaussian splatting mesh (expected 1)`);
    check(/SwiftShader|ANGLE/i.test(info.renderer), `${name}: WebGL renderer "${info.renderer}"`);
    if (name.startsWith('player_model')) {
      // A real capture fills the frame. With the default blur (0.075 px² in 3DGS's terms) the PSNR
      // is only reported (BENCHMARKS.md: 29.6-31.2 dB on Panoptic); the orientation is checked.
      if (scene.kernel) checkFullFrame(name, stats, 35);
      else checkOrientation(name, stats);
    } else if (name.startsWith('player_lego_quantized')) {
      // The quantised file against the plain one, both drawn by Babylon.js: only the quantisation
      // differs. THRESHOLD_QUANTIZED (below) is far above what a wrong dequantisation gives.
      check(stats.iou >= 0.98, `${name}: foreground IoU ${stats.iou.toFixed(3)} against the plain export's picture >= 0.98`);
      check(stats.psnr >= THRESHOLD_QUANTIZED,
            `${name}: PSNR ${stats.psnr.toFixed(2)} dB against the plain export's picture >= ${THRESHOLD_QUANTIZED} dB`);
    } else if (scene.truth && name.startsWith('player_lego_baked')) {
      // Baking must not take Babylon's picture further from our textured render than the unbaked
      // export with the same blur (BENCHMARKS.md, issue 21, "Textures baked for KHR-only players").
      const unbaked = vsTextured[name.replace('player_lego_baked', 'player_lego')];
      console.log(`${name}: against our textured render ${stats.psnrVsAtexTextured.toFixed(2)} dB baked, ` +
                  `${unbaked.toFixed(2)} dB unbaked`);
      check(stats.iou >= 0.9, `${name}: foreground IoU ${stats.iou.toFixed(3)} >= 0.9`);
      // The lego's textures are faint (our renders with and without them are 51.5 dB apart), so
      // baking cannot gain visibly here; the guard is that it costs nothing.
      check(stats.psnrVsAtexTextured > unbaked - BAKE_TOLERANCE_DB,
            `${name}: PSNR against our textured render ${stats.psnrVsAtexTextured.toFixed(2)} dB > unbaked ` +
            `${unbaked.toFixed(2)} dB - ${BAKE_TOLERANCE_DB} dB`);
    } else if (scene.truth) {
      // Issue 21's target for the untextured content is 35 dB against our render of it. With its
      // default blur (0.3 px² added to splats of twice the glTF's scales: 0.075 px² in 3DGS's terms)
      // Babylon.js 9.28 reaches 22.0 dB on this 100x100 view; with 3DGS's 0.3 px² (kernel=1.2) it must
      // reach the target (BENCHMARKS.md, "A trained asset in Babylon.js").
      const floor = scene.kernel ? 35 : 20;
      check(stats.iou >= 0.9, `${name}: foreground IoU ${stats.iou.toFixed(3)} >= 0.9`);
      check(stats.psnr >= floor, `${name}: PSNR ${stats.psnr.toFixed(2)} dB against our untextured render >= ${floor} dB`);
      check(stats.iouUpsideDown < stats.iou - 0.1, `${name}: the upside-down picture matches worse (IoU ${stats.iouUpsideDown.toFixed(3)})`);
    } else if (scene.untextured) {
      // Semi-transparent splats: the foreground mask is threshold-sensitive (0.886 unbaked).
      check(stats.iou >= 0.8, `${name}: foreground IoU ${stats.iou.toFixed(3)} >= 0.8`);
      if (name === 'textured_tiles_baked') {
        const unbaked = vsTextured.textured_tiles;
        console.log(`textured tiles against our textured render: ${unbaked.toFixed(2)} dB unbaked, ` +
                    `${stats.psnr.toFixed(2)} dB baked`);
        check(stats.psnr > unbaked + TILES_MARGIN_DB,
              `${name}: PSNR against our textured render ${stats.psnr.toFixed(2)} dB > unbaked ` +
              `${unbaked.toFixed(2)} dB + ${TILES_MARGIN_DB} dB`);
      }
    } else if (name.startsWith('letter_f')) {
      check(stats.iou >= 0.9, `${name}: foreground IoU ${stats.iou.toFixed(3)} >= 0.9`);
      for (const c of ['Red', 'Green', 'Blue']) {
        check(stats[`iou${c}`] >= 0.85, `${name}: ${c.toLowerCase()} IoU ${stats[`iou${c}`].toFixed(3)} >= 0.85`);
      }
      check(stats.iouUpsideDown < stats.iou - 0.25,
            `${name}: the upside-down picture matches clearly worse (IoU ${stats.iouUpsideDown.toFixed(3)})`);
      check(stats.psnr >= 35, `${name}: PSNR ${stats.psnr.toFixed(2)} dB >= 35 dB`);
    } else {
      check(stats.iou >= 0.9, `${name}: foreground IoU ${stats.iou.toFixed(3)} >= 0.9`);
      check(stats.psnr >= 28, `${name}: PSNR ${stats.psnr.toFixed(2)} dB >= 28 dB`);
      check(stats.iouUpsideDown < stats.iou - 0.1, `${name}: the upside-down picture matches worse (IoU ${stats.iouUpsideDown.toFixed(3)})`);
    }
    await page.close();
  }
  if (only) {
    // experiments: no upright check
  } else if (manifest.upright) {
    const page = await context.newPage();
    await page.setViewportSize({ width: 160, height: 120 });
    const errors = [];
    page.on('pageerror', (e) => errors.push(e.message));
    await page.goto(`${server.url}/index.html?src=/data/${manifest.upright.glb}`);
    try {
      await page.waitForFunction(() => window.atexView !== undefined, null, { timeout: 60000 });
      await page.evaluate(() => window.atexView.ready);
      const shown = await page.evaluate((up) => {
        // Babylon matrices act on row vectors: v' = v M (m[4 r + c]); a direction ignores m[12..14].
        const m = window.atexViewer.ctx.splats[0].computeWorldMatrix(true).m;
        const v = [0, 1, 2].map((c) => up[0] * m[c] + up[1] * m[4 + c] + up[2] * m[8 + c]);
        const length = Math.hypot(...v);
        return v.map((x) => x / length);
      }, manifest.upright.cameras_up);
      console.log(`upright: the lego cameras' up direction is (${shown.map((x) => x.toFixed(3)).join(', ')}) in Babylon's world`);
      check(shown[1] > Math.cos(Math.PI / 6), `upright: the lego sample's up direction points up in Babylon.js (y = ${shown[1].toFixed(3)} > cos 30 degrees)`);
    } catch (e) {
      check(false, `upright: Babylon.js did not load the lego sample: ${e.message} ${errors.join(' | ')}`);
    }
    await page.close();
  } else if (process.env.ATEX_REQUIRE_DATA === '1') {
    check(false, `real data for the upright check is missing (${manifest.upright_missing})`);
  }
  check(offline.length === 0, `no request left 127.0.0.1 (${offline.slice(0, 3).join(', ')})`);
} finally {
  await browser.close();
  await server.close();
}
fs.writeFileSync(path.join(dir, 'babylon_results.json'), JSON.stringify(results, null, 2));
console.log(`browser checks took ${((Date.now() - started) / 1000).toFixed(1)} s`);
finish();
