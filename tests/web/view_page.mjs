// The page of `atex view` in headless Debian Chromium (software WebGL2 through SwiftShader),
// opened straight from disk (file://, no server), every request outside file:/data: refused.
// At each time given, the page's picture from its opening camera (#fixed=1: the camera's
// exact size and intrinsics) is compared with libatex's reference render of the same camera
// and time (`atex render --time`, written by view_page.sh):
//   - not blank: at least 2% of the pixels differ from the background;
//   - the splats land where ours do: foreground IoU >= 0.85 (foreground: a pixel more than
//     0.1 from the background in some channel). The mask test is what catches a wrong
//     projection, a mirrored or upside-down world or a wrong time; IoU of the upside-down
//     picture must be clearly lower, so the check can tell;
//   - PSNR >= 26 dB against our render. The page shows an approximation of the asset: each
//     texture is replaced by its average and the motion is interpolated between keyframes,
//     8-bit blending; see view_page.sh for the figures this threshold leaves room under.
// Side-by-side pictures (page left, libatex right) are written as view_t*_page_vs_atex.png.
// Usage: node view_page.mjs DIR  (DIR holds view.html, view.json and reference_*.png)
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { check, finish, missing } from './common.mjs';

const dir = path.resolve(process.argv[2] || '.');
const summary = JSON.parse(fs.readFileSync(path.join(dir, 'view.json'), 'utf8'));
const references = JSON.parse(fs.readFileSync(path.join(dir, 'references.json'), 'utf8'));
const chromiumPath = process.env.ATEX_CHROMIUM || '/usr/bin/chromium';
if (!fs.existsSync(chromiumPath)) missing(`${chromiumPath} is missing (apt-get install chromium)`);
let chromium;
try {
  ({ chromium } = await import('playwright-core'));
} catch {
  missing('npm package playwright-core is missing: run tests/web/install.sh');
}

// Runs in the page: shows `time`, then compares the canvas with the reference PNG (base64).
async function compareInPage({ time, referencePng, background }) {
  const shown = window.atexView.show(time);
  const gl = window.atexView.canvas;
  const w = gl.width, h = gl.height;
  const bytes = Uint8Array.from(atob(referencePng), (c) => c.charCodeAt(0));
  const ref = await createImageBitmap(new Blob([bytes], { type: 'image/png' }));
  if (ref.width !== w || ref.height !== h) throw new Error(`canvas ${w}x${h} vs reference ${ref.width}x${ref.height}`);
  const canvas = new OffscreenCanvas(2 * w, h);
  const g = canvas.getContext('2d', { willReadFrequently: true });
  g.drawImage(gl, 0, 0);
  g.drawImage(ref, w, 0);
  const a = g.getImageData(0, 0, w, h).data;  // the page
  const b = g.getImageData(w, 0, w, h).data;  // libatex
  const bg = background.map((v) => Math.round(255 * v));
  const fg = (p, i) => Math.max(Math.abs(p[i] - bg[0]), Math.abs(p[i + 1] - bg[1]), Math.abs(p[i + 2] - bg[2])) > 25;
  const iou = (flip) => {
    let inter = 0, union = 0;
    for (let y = 0; y < h; ++y) {
      for (let x = 0; x < w; ++x) {
        const fa = fg(a, ((flip ? h - 1 - y : y) * w + x) * 4), fb = fg(b, (y * w + x) * 4);
        if (fa || fb) union++;
        if (fa && fb) inter++;
      }
    }
    return union ? inter / union : 1;
  };
  let se = 0, fgA = 0;
  for (let i = 0; i < a.length; i += 4) {
    for (let c = 0; c < 3; ++c) se += ((a[i + c] - b[i + c]) / 255) ** 2;
    fgA += fg(a, i) ? 1 : 0;
  }
  const mse = se / (w * h * 3);
  const blob = await canvas.convertToBlob({ type: 'image/png' });
  const png = new Uint8Array(await blob.arrayBuffer());
  let binary = '';
  for (let i = 0; i < png.length; i += 0x8000) binary += String.fromCharCode(...png.subarray(i, i + 0x8000));
  return {
    width: w, height: h, drawn: shown.drawn,
    iou: iou(false), iouUpsideDown: iou(true),
    psnr: mse > 0 ? -10 * Math.log10(mse) : 99,
    foreground: fgA / (w * h),
    sideBySidePng: btoa(binary),
  };
}

const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'atex-chromium-'));
const started = Date.now();
let context;
try {
  context = await chromium.launchPersistentContext(profile, {
    executablePath: chromiumPath,
    headless: true,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
           '--disable-sync', '--no-first-run', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
    deviceScaleFactor: 1,
    viewport: { width: summary.camera.width, height: summary.camera.height },
  });
  const outside = [];
  await context.route('**/*', (route) => {
    const url = new URL(route.request().url());
    if (url.protocol === 'file:' || url.protocol === 'data:' || url.protocol === 'blob:') return route.continue();
    outside.push(url.href);
    return route.abort();
  });
  const page = await context.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  const t0 = Date.now();
  await page.goto(`file://${path.join(dir, 'view.html')}#fixed=1&t=${references[0].time}`, { timeout: 120000 });
  let info;
  try {
    await page.waitForFunction(() => window.atexView !== undefined, null, { timeout: 120000 });
    info = await page.evaluate(() => window.atexView.ready);
  } catch (e) {
    check(false, `the page did not render: ${e.message} ${errors.join(' | ')}`);
    info = null;
  }
  if (info) {
    console.log(`page ready in ${((Date.now() - t0) / 1000).toFixed(1)} s: ${JSON.stringify(info)}`);
    check(info.count === summary.kept, `the page holds ${info.count} Gaussians (atex view kept ${summary.kept})`);
    check(info.frames === summary.frames, `the page holds ${info.frames} keyframes (atex view baked ${summary.frames})`);
    check(/SwiftShader|ANGLE/i.test(info.renderer), `WebGL renderer "${info.renderer}"`);
    for (const ref of references) {
      const referencePng = fs.readFileSync(path.join(dir, ref.png)).toString('base64');
      const stats = await page.evaluate(compareInPage, { time: ref.time, referencePng, background: summary.background });
      const name = `view_t${ref.time}`;
      fs.writeFileSync(path.join(dir, `${name}_page_vs_atex.png`), Buffer.from(stats.sideBySidePng, 'base64'));
      delete stats.sideBySidePng;
      console.log(`${name}: ${JSON.stringify(stats)}`);
      check(stats.foreground >= 0.02, `${name}: the picture is not blank (${(100 * stats.foreground).toFixed(1)}% foreground)`);
      check(stats.iou >= 0.85, `${name}: foreground IoU ${stats.iou.toFixed(3)} >= 0.85 against atex render`);
      check(stats.iouUpsideDown < stats.iou - 0.15, `${name}: the upside-down picture matches clearly worse (IoU ${stats.iouUpsideDown.toFixed(3)})`);
      check(stats.psnr >= 26, `${name}: PSNR ${stats.psnr.toFixed(2)} dB >= 26 dB against atex render`);
    }
  }
  check(errors.length === 0, `no page errors (${errors.slice(0, 3).join(' | ')})`);
  check(outside.length === 0, `no request left the file (${outside.slice(0, 3).join(', ')})`);
} finally {
  if (context) await context.close();
  fs.rmSync(profile, { recursive: true, force: true });
}
console.log(`browser check took ${((Date.now() - started) / 1000).toFixed(1)} s`);
finish();
