// Writes the third-party fixtures of libatex's splat reader tests from one INRIA
// 3DGS PLY, with unmodified npm packages (versions pinned in package-lock.json):
//   OUT/src.compressed.ply  PlayCanvas splat-transform (compressed PLY)
//   OUT/src.sog, OUT/sog/meta.json + images   splat-transform (SOG v2, bundled and not)
//   OUT/src.splat           gsplat.js (huggingface) SplatData.serialize
//   OUT/src.l0|l1|l2.ksplat mkkellogg GaussianSplats3D PlyLoader -> SplatBuffer, compression levels 0..2
// and, for every file above, OUT/<file>.ref.ply: splat-transform's own decoding of it
// back to a plain PLY (the reference our readers are compared with).
//
// Usage: node make_fixtures.mjs SOURCE.ply OUT_DIR [EXTRA_INPUT ...]
//   EXTRA_INPUT (e.g. a shared SOG meta.json) is only decoded to OUT/extra_<i>.ref.ply.
import fs from 'node:fs';
import path from 'node:path';
import { execFileSync } from 'node:child_process';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const [source, out, ...extra] = process.argv.slice(2);
if (!source || !out) {
  console.error('usage: node make_fixtures.mjs SOURCE.ply OUT_DIR [EXTRA_INPUT ...]');
  process.exit(2);
}
fs.mkdirSync(path.join(out, 'sog'), { recursive: true });
const cli = path.join(here, 'node_modules', '@playcanvas', 'splat-transform', 'bin', 'cli.mjs');
const transform = (input, output) =>
  execFileSync(process.execPath, [cli, '-q', '-w', '-g', 'cpu', input, output], { stdio: ['ignore', 'ignore', 'inherit'] });

const bytes = fs.readFileSync(source);
const arrayBuffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.length);

transform(source, path.join(out, 'src.compressed.ply'));
transform(source, path.join(out, 'src.sog'));
transform(source, path.join(out, 'sog', 'meta.json'));

const gsplat = await import('gsplat');
const splat = gsplat.PLYLoader.LoadFromArrayBuffer(arrayBuffer, new gsplat.Scene());
fs.writeFileSync(path.join(out, 'src.splat'), splat.data.serialize());

globalThis.window ??= globalThis;  // GaussianSplats3D's loader schedules work through window.setTimeout
const gs3d = await import('@mkkellogg/gaussian-splats-3d');
for (const level of [0, 1, 2]) {
  const buffer = await gs3d.PlyLoader.loadFromFileData(arrayBuffer.slice(0), 0, level, true, 2);
  fs.writeFileSync(path.join(out, `src.l${level}.ksplat`), new Uint8Array(buffer.bufferData));
}

for (const name of ['src.compressed.ply', 'src.sog', 'src.splat', 'src.l0.ksplat', 'src.l1.ksplat', 'src.l2.ksplat']) {
  transform(path.join(out, name), path.join(out, name + '.ref.ply'));
}
extra.forEach((input, i) => transform(input, path.join(out, `extra_${i}.ref.ply`)));
