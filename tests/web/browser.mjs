// What the browser checks of tests/web share: headless Debian Chromium with software WebGL2
// (SwiftShader) through playwright-core, every request off 127.0.0.1 refused, and the in-page
// comparison of a player's canvas with one of libatex's reference renders.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { missing } from './common.mjs';

// Starts Chromium (or skips/fails through missing() when it or playwright-core is absent).
// Resolves to { context, offline, close }: `offline` collects the URLs that were refused.
export async function openBrowser() {
  const chromiumPath = process.env.ATEX_CHROMIUM || '/usr/bin/chromium';
  if (!fs.existsSync(chromiumPath)) missing(`${chromiumPath} is missing (apt-get install chromium)`);
  let chromium;
  try {
    ({ chromium } = await import('playwright-core'));
  } catch {
    missing('npm package playwright-core is missing: run tests/web/install.sh');
  }
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'atex-chromium-'));
  let context;
  try {
    context = await chromium.launchPersistentContext(profile, {
      executablePath: chromiumPath,
      headless: true,
      args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
             '--disable-sync', '--no-first-run', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
      deviceScaleFactor: 1,
      viewport: { width: 800, height: 600 },
    });
  } catch (e) {
    fs.rmSync(profile, { recursive: true, force: true });
    throw e;
  }
  const offline = [];
  await context.route('**/*', (route) => {
    const url = new URL(route.request().url());
    if (url.hostname === '127.0.0.1' || url.protocol === 'data:' || url.protocol === 'blob:') return route.continue();
    offline.push(url.href);
    return route.abort();
  });
  return {
    context,
    offline,
    close: async () => {
      await context.close();
      fs.rmSync(profile, { recursive: true, force: true });
    },
  };
}

// A new page whose errors (uncaught exceptions, console errors, HTTP errors) land in `errors`.
export async function newWatchedPage(context, width, height) {
  const page = await context.newPage();
  await page.setViewportSize({ width, height });
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('response', (r) => { if (r.status() >= 400) errors.push(`HTTP ${r.status()} ${r.url()}`); });
  return { page, errors };
}

// Runs in the page (page.evaluate): compares the player's canvas (window.atexView.canvas) with
// a reference PNG of the same size: foreground IoU overall and per dominant colour, the same
// IoU against the picture turned upside down and mirrored left-right, PSNR (and PSNR against
// the reference with red and blue swapped, and of the picture turned upside down and mirrored:
// the orientation guards of full-frame scenes, where foreground IoU means little), a side-by-side PNG (player left) and the player's
// picture alone (PNGs as base64).
export async function compareInPage(referenceUrl) {
  const gl = window.atexView.canvas;
  const w = gl.width, h = gl.height;
  const ref = await createImageBitmap(await (await fetch(referenceUrl)).blob());
  if (ref.width !== w || ref.height !== h) throw new Error(`canvas ${w}x${h} vs reference ${ref.width}x${ref.height}`);
  const canvas = new OffscreenCanvas(2 * w, h);
  const g = canvas.getContext('2d', { willReadFrequently: true });
  g.drawImage(gl, 0, 0);
  g.drawImage(ref, w, 0);
  const a = g.getImageData(0, 0, w, h).data;  // the player
  const b = g.getImageData(w, 0, w, h).data;  // reference
  const fg = (p, i) => Math.max(p[i], p[i + 1], p[i + 2]) > 25;
  const cls = (p, i) => (p[i] >= p[i + 1] && p[i] >= p[i + 2] ? 0 : p[i + 1] >= p[i + 2] ? 1 : 2);
  // flipA: compare the player's picture upside down; mirrorA: left-right mirrored.
  const iou = (flipA, mirrorA = false) => {
    const inter = [0, 0, 0, 0], union = [0, 0, 0, 0];
    for (let y = 0; y < h; ++y) {
      for (let x = 0; x < w; ++x) {
        const ia = ((flipA ? h - 1 - y : y) * w + (mirrorA ? w - 1 - x : x)) * 4, ib = (y * w + x) * 4;
        const fa = fg(a, ia), fb = fg(b, ib);
        if (fa || fb) union[3]++;
        if (fa && fb) inter[3]++;
        for (let c = 0; c < 3; ++c) {
          const ca = fa && cls(a, ia) === c, cb = fb && cls(b, ib) === c;
          if (ca || cb) union[c]++;
          if (ca && cb) inter[c]++;
        }
      }
    }
    return inter.map((v, k) => (union[k] ? v / union[k] : 1));
  };
  // se: squared error; seSwapped: the same against the reference with red and blue swapped
  // (what a player reading the colour channels in the wrong order would score).
  // seUpsideDown, seMirrored: the player's picture turned upside down / mirrored left-right.
  let se = 0, seSwapped = 0, seUpsideDown = 0, seMirrored = 0, fgA = 0, fgB = 0;
  for (let i = 0; i < a.length; i += 4) {
    const x = (i / 4) % w, y = Math.floor(i / 4 / w);
    const iu = ((h - 1 - y) * w + x) * 4, im = (y * w + w - 1 - x) * 4;
    for (let c = 0; c < 3; ++c) {
      se += ((a[i + c] - b[i + c]) / 255) ** 2;
      seSwapped += ((a[i + c] - b[i + 2 - c]) / 255) ** 2;
      seUpsideDown += ((a[iu + c] - b[i + c]) / 255) ** 2;
      seMirrored += ((a[im + c] - b[i + c]) / 255) ** 2;
    }
    fgA += fg(a, i) ? 1 : 0;
    fgB += fg(b, i) ? 1 : 0;
  }
  const n = w * h * 3;
  const db = (sum) => (sum > 0 ? -10 * Math.log10(sum / n) : 99);
  const png = async (c) => {
    const bytes = new Uint8Array(await (await c.convertToBlob({ type: 'image/png' })).arrayBuffer());
    let binary = '';
    for (let i = 0; i < bytes.length; i += 0x8000) binary += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
    return btoa(binary);
  };
  const alone = new OffscreenCanvas(w, h);
  alone.getContext('2d').drawImage(gl, 0, 0);
  const [r, gr, bl, all] = iou(false);
  return {
    width: w, height: h,
    iou: all, iouRed: r, iouGreen: gr, iouBlue: bl,
    iouUpsideDown: iou(true)[3], iouMirrored: iou(false, true)[3],
    psnr: db(se), psnrRedBlueSwapped: db(seSwapped), psnrUpsideDown: db(seUpsideDown), psnrMirrored: db(seMirrored),
    foregroundPlayer: fgA / (w * h), foregroundReference: fgB / (w * h),
    sideBySidePng: await png(canvas),
    playerPng: await png(alone),
  };
}
