// Loads our exports in unmodified third-party players in headless Debian Chromium (software
// WebGL2, SwiftShader), driven by playwright-core, and compares each picture with libatex's
// reference render of the same camera (pages in tests/web/players/):
//   playcanvas  the PlayCanvas engine (npm playcanvas): our .glb (its KHR_gaussian_splatting
//               loader) and our .ply (its gsplat loader)
//   spark       three.js (npm three) with Spark (npm @sparkjsdev/spark): our .ply and .spz
//               (Spark reads no glTF)
// Files: what `atex export` / `atex convert` write (tests/web/web_fixture.cc). A .ply is in the
// 3DGS convention (y down, z forward) and is shown turned 180 degrees about x (the usual way to
// show such a file in a y-up player); a .spz (RUB axes) and a .glb are shown as they are.
// Scenes:
//   letter_f     a red/green/blue "F" under a camera stated in glTF terms (+z, +y up):
//                per-colour foreground IoU (position, colours), and the same picture upside
//                down and mirrored must match clearly worse (upright, not mirrored)
//   player_lego  the bundled lego sample baked at its test view 0's time, under that view's
//                camera: PSNR against our render of its Gaussians without textures (reported
//                also against our textured render and the ground truth), guarded by a bound
//                that a wrong axis (IoU, upside down) or wrong colours (red/blue swapped) fail;
//                upright: the up direction of the lego's dataset cameras, carried into the
//                player's world by the glTF node rotation that the page's camera uses, is +y
//   player_lego_3dgs_kernel  (PlayCanvas) the same with the page's ?kernel=3dgs: PlayCanvas drawing
//                splats as 3DGS training does through its public shader-chunk hooks
//                (samples/web/playcanvas_3dgs.mjs); must reach issue 21's 35 dB
//   player_model_vN(_3dgs_kernel)  an external trained model (bench/web_players_model.sh; the
//                fixture's optional ATEX_PLAYER_MODEL) at test view N's time and camera, with the
//                player's settings as for player_lego (and PlayCanvas's ?kernel=3dgs): full-frame
//                checks (common.mjs checkFullFrame): PSNR against our render >= 35 dB where the
//                player draws splats as 3DGS does; red/blue-swapped, upside-down and mirrored
//                pictures must score clearly worse
// Pictures: PLAYER_SCENE_FORMAT.png, and side by side with libatex's (player left) as
// PLAYER_SCENE_FORMAT_vs_atex.png.
// Usage: node player_render.mjs playcanvas|spark FIXTURE_DIR
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { compareInPage, newWatchedPage, openBrowser } from './browser.mjs';
import { check, checkFullFrame, checkOrientation, finish, missing, readManifest } from './common.mjs';
import { startServer } from './serve.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const player = process.argv[2];
// Per player: its page, the formats it loads, the page settings, and the bounds of the checks.
//   PlayCanvas runs with its defaults (it has no setting for the dilation). Its shader adds 0.3 to
//   a 2D covariance computed with twice the pixel focal length (viewport x P00), i.e. 0.075 px^2
//   where 3DGS training (and our renderer) adds 0.3 px^2, so pixel-sized splats come out smaller:
//   the 100x100 lego scores 20.3 dB against our render. Its F's faint fringe is also narrower
//   (foreground IoU 0.88, Spark 0.99; its kernel is lowered by e^-4 to reach zero at its cut,
//   2.83 sigma). Its kernelScene draws the lego again with the page's ?kernel=3dgs, which undoes
//   all three through the engine's documented splat shader hooks (44.8 dB on the CPU machine).
//   Spark runs with the setting its documentation names for scenes trained without
//   anti-aliasing, as ours are: preBlurAmount 0.3 (the 3DGS dilation) and blurAmount 0 (its
//   default, 0.3 with opacity compensation, is Mip-Splatting's convention and scores 15.9 dB).
const players = {
  playcanvas: { page: 'playcanvas.html', formats: ['glb', 'ply'], module: 'playcanvas/package.json', query: {},
                letterIou: 0.8, letterColourIou: 0.75, legoPsnr: 18,
                kernelScene: { name: 'player_lego_3dgs_kernel', query: { kernel: '3dgs' }, legoPsnr: 35 } },
  spark: { page: 'spark.html', formats: ['ply', 'spz'], module: '@sparkjsdev/spark/package.json',
           query: { spark: JSON.stringify({ preBlurAmount: 0.3, blurAmount: 0 }) },
           letterIou: 0.9, letterColourIou: 0.85, legoPsnr: 35 },
};
if (!players[player]) {
  console.error('usage: node player_render.mjs playcanvas|spark FIXTURE_DIR');
  process.exit(2);
}
const { page: pageName, formats, module, query: settings, letterIou, letterColourIou, legoPsnr, kernelScene } = players[player];
if (!fs.existsSync(path.join(here, 'node_modules', module))) {
  missing(`npm package ${module.replace('/package.json', '')} is missing: run tests/web/install.sh`);
}
const dir = path.resolve(process.argv[3] || '.');
const manifest = readManifest(dir);
if (!manifest.player_lego && process.env.ATEX_REQUIRE_DATA === '1') {
  check(false, `real data for the lego scene is missing (${manifest.upright_missing})`);
}

// The lego's PSNR guard (legoPsnr above): issue 21's target against our render, 35 dB, where the
// player draws splats as 3DGS does (Spark so set, PlayCanvas with ?kernel=3dgs); below what
// PlayCanvas shows with its defaults otherwise.
// Either must be failed by the same picture against the reference with red and blue swapped
// (checked on every run: a wrong colour order or axis cannot pass).

// The glTF node rotation (x, y, z, w) of a .glb's splat node.
function glbNodeRotation(file) {
  const bytes = fs.readFileSync(file);
  const json = JSON.parse(bytes.subarray(20, 20 + bytes.readUInt32LE(12)).toString('utf8'));
  const node = (json.nodes || []).find((n) => n.mesh !== undefined) || {};
  return node.rotation || [0, 0, 0, 1];
}
function rotate([x, y, z, w], v) {
  const t = [2 * (y * v[2] - z * v[1]), 2 * (z * v[0] - x * v[2]), 2 * (x * v[1] - y * v[0])];
  return [v[0] + w * t[0] + (y * t[2] - z * t[1]), v[1] + w * t[1] + (z * t[0] - x * t[2]),
          v[2] + w * t[2] + (x * t[1] - y * t[0])];
}

const server = await startServer({ data: dir });
const started = Date.now();
const browser = await openBrowser();
const { context, offline } = browser;
const results = [];
try {
  const only = process.env.ATEX_PLAYER_SCENES;  // experiments: a comma-separated subset of scenes
  // [name, fixture scene, page settings, the lego's PSNR bound]
  const scenes = [['letter_f', manifest.letter_f, settings, legoPsnr]];
  if (manifest.player_lego) {
    scenes.push(['player_lego', manifest.player_lego, settings, legoPsnr]);
    if (kernelScene) {
      scenes.push([kernelScene.name, manifest.player_lego, { ...settings, ...kernelScene.query }, kernelScene.legoPsnr]);
    }
  }
  for (const model of manifest.player_model || []) {
    scenes.push([model.name, model, settings, legoPsnr]);
    if (kernelScene) {
      scenes.push([`${model.name}_3dgs_kernel`, model, { ...settings, ...kernelScene.query }, kernelScene.legoPsnr]);
    }
  }
  for (const [name, scene, pageSettings, floor] of scenes.filter(([n]) => !only || only.split(',').includes(n))) {
    for (const format of formats.filter((f) => !process.env.ATEX_PLAYER_FORMATS || process.env.ATEX_PLAYER_FORMATS.split(',').includes(f))) {
      const label = `${player} ${name}.${format}`;
      const camera = JSON.parse(fs.readFileSync(path.join(dir, scene.camera), 'utf8'));
      const { page, errors } = await newWatchedPage(context, camera.width, camera.height);
      const query = new URLSearchParams({ src: `/data/${scene[format]}`, camera: `/data/${scene.camera}`, ...pageSettings });
      if (format === 'ply') query.set('turn', 'x180');
      // ATEX_PLAYER_QUERY=a=1&b=2 adds page parameters (experiments with a player's settings).
      for (const [k, v] of new URLSearchParams(process.env.ATEX_PLAYER_QUERY || '')) query.set(k, v);
      if (camera.pose.apply_node_rotation) query.set('rotation', `/data/${scene.glb}`);
      const t0 = Date.now();
      await page.goto(`${server.url}/players/${pageName}?${query}`);
      let info;
      try {
        // A page whose modules fail to load never defines atexView: stop at its first error.
        await Promise.race([page.waitForFunction(() => window.atexView !== undefined, null, { timeout: 60000 }),
                            new Promise((_, reject) => page.once('pageerror', reject))]);
        info = await page.evaluate(() => window.atexView.ready);
      } catch (e) {
        check(false, `${label}: the player did not render: ${e.message.split('\n')[0]} ${errors.slice(0, 3).join(' | ')}`);
        await page.close();
        continue;
      }
      // ATEX_PLAYER_REFERENCE=FILE (in FIXTURE_DIR) compares with another picture (experiments).
      const reference = process.env.ATEX_PLAYER_REFERENCE || scene.reference;
      const stats = await page.evaluate(compareInPage, `/data/${reference}`);
      const stem = `${player}_${name}_${format}`;
      fs.writeFileSync(path.join(dir, `${stem}_vs_atex.png`), Buffer.from(stats.sideBySidePng, 'base64'));
      fs.writeFileSync(path.join(dir, `${stem}.png`), Buffer.from(stats.playerPng, 'base64'));
      delete stats.sideBySidePng;
      delete stats.playerPng;
      if (scene.truth) {
        stats.psnrVsAtexTextured = (await page.evaluate(compareInPage, `/data/${scene.atex}`)).psnr;
        stats.psnrVsTruth = (await page.evaluate(compareInPage, `/data/${scene.truth}`)).psnr;
        if (scene.clamped) {
          // Diagnostic: our render with each base colour clamped to [0, 1] (web_fixture_player.h).
          stats.psnrVsClamped = (await page.evaluate(compareInPage, `/data/${scene.clamped}`)).psnr;
        }
      }
      const seconds = (Date.now() - t0) / 1000;
      console.log(`${label}: ${JSON.stringify({ ...info, ...stats, seconds })}`);
      results.push({ player, scene: name, format, settings: pageSettings, view: scene.view, time: scene.time,
                     ...info, ...stats, seconds });
      check(errors.length === 0, `${label}: no page errors (${errors.slice(0, 3).join(' | ')})`);
      check(/SwiftShader|ANGLE/i.test(info.renderer), `${label}: WebGL renderer "${info.renderer}"`);
      check(info.splats === scene.gaussians, `${label}: the player holds ${info.splats} splats (the file: ${scene.gaussians})`);
      if (name === 'letter_f') {
        check(stats.iou >= letterIou, `${label}: foreground IoU ${stats.iou.toFixed(3)} >= ${letterIou}`);
        for (const c of ['Red', 'Green', 'Blue']) {
          const v = stats[`iou${c}`];
          check(v >= letterColourIou, `${label}: ${c.toLowerCase()} IoU ${v.toFixed(3)} >= ${letterColourIou}`);
        }
        check(stats.psnr >= 35, `${label}: PSNR ${stats.psnr.toFixed(2)} dB >= 35 dB`);
        check(stats.iouUpsideDown < stats.iou - 0.25, `${label}: upside down matches clearly worse (IoU ${stats.iouUpsideDown.toFixed(3)})`);
        check(stats.iouMirrored < stats.iou - 0.25, `${label}: mirrored matches clearly worse (IoU ${stats.iouMirrored.toFixed(3)})`);
      } else if (name.startsWith('player_model')) {
        // Issue 21's 35 dB where the player draws splats as 3DGS does; with PlayCanvas's defaults
        // the PSNR is only reported (its dilation, and the splats it draws in front of the near
        // plane: BENCHMARKS.md, "A trained Panoptic model in the players").
        if (floor >= 35) checkFullFrame(label, stats, floor);
        else checkOrientation(label, stats);
      } else {
        check(stats.iou >= 0.9, `${label}: foreground IoU ${stats.iou.toFixed(3)} >= 0.9`);
        check(stats.psnr >= floor, `${label}: PSNR ${stats.psnr.toFixed(2)} dB against our untextured render >= ${floor} dB`);
        check(stats.psnrRedBlueSwapped < floor,
              `${label}: with red and blue swapped the guard fails (${stats.psnrRedBlueSwapped.toFixed(2)} dB < ${floor} dB)`);
        check(stats.iouUpsideDown < stats.iou - 0.1, `${label}: upside down matches worse (IoU ${stats.iouUpsideDown.toFixed(3)})`);
        check(stats.iouMirrored < stats.iou - 0.05, `${label}: mirrored matches worse (IoU ${stats.iouMirrored.toFixed(3)})`);
        if (manifest.upright) {
          const shown = rotate(glbNodeRotation(path.join(dir, scene.glb)), manifest.upright.cameras_up);
          const y = shown[1] / Math.hypot(...shown);
          check(y > Math.cos(Math.PI / 6), `${label}: the lego cameras' up direction is up in the player's world (y = ${y.toFixed(3)})`);
        }
      }
      await page.close();
    }
  }
  check(offline.length === 0, `no request left 127.0.0.1 (${offline.slice(0, 3).join(', ')})`);
} finally {
  await browser.close();
  await server.close();
}
fs.writeFileSync(path.join(dir, `${player}_results.json`), JSON.stringify(results, null, 2));
console.log(`browser checks took ${((Date.now() - started) / 1000).toFixed(1)} s`);
finish();
