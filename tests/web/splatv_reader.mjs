// Reads our .splatv the way splaTV's viewer does and checks the motion against our
// deformation. The reading is a re-implementation of antimatter15/splaTV hybrid.js:
// readChunks() streams the file through a ReadableStream reader into the chunk list
// (8-byte "magic" chunk -> JSON "chunks" chunk -> the listed chunks), chunkHandler()
// checks the magic 0x674b and takes the "splat" chunk's bytes as the RGBA32UI texture
// (vertexCount = floor(bytes / 64)), and position() is the vertex shader's
// static xyz + d1 dt + d2 dt^2 + d3 dt^3 with dt = time - trbf_center, in float32.
// Positions at several times must match the deformation (motion_reference.json) within
// the fit error the exporter reported.
// Usage: node splatv_reader.mjs FIXTURE_DIR
import fs from 'node:fs';
import path from 'node:path';
import { check, finish, readManifest } from './common.mjs';

const dir = path.resolve(process.argv[2] || '.');
const manifest = readManifest(dir);

// --- the viewer's reader -------------------------------------------------------------
async function readChunks(reader, chunks, handleChunk) {
  let chunk = chunks.shift();
  let buffer = new Uint8Array(chunk.size);
  let offset = 0;
  while (chunk) {
    let { done, value } = await reader.read();
    if (done) break;
    while (value.length + offset >= chunk.size) {
      buffer.set(value.subarray(0, chunk.size - offset), offset);
      value = value.subarray(chunk.size - offset);
      handleChunk(chunk, buffer.buffer, 0, chunks);
      chunk = chunks.shift();
      if (!chunk) break;
      buffer = new Uint8Array(chunk.size);
      offset = 0;
    }
    if (!chunk) break;
    buffer.set(value, offset);
    offset += value.length;
    handleChunk(chunk, buffer.buffer, buffer.byteLength - offset, chunks);
  }
  if (chunk) handleChunk(chunk, buffer.buffer, 0, chunks);
}

async function loadSplatv(bytes) {
  const state = { cameras: null, texture: null, texwidth: 0, texheight: 0, vertexCount: 0, chunks: null };
  const handler = (chunk, buffer, remaining, chunks) => {
    if (!remaining && chunk.type === 'magic') {
      const intView = new Uint32Array(buffer);
      if (intView[0] !== 0x674b) throw new Error('This does not look like a splatv file');
      chunks.push({ size: intView[1], type: 'chunks' });
    } else if (!remaining && chunk.type === 'chunks') {
      state.chunks = JSON.parse(new TextDecoder('utf-8').decode(buffer));
      for (const c of state.chunks) {
        chunks.push(c);
        if (c.type === 'splat') state.cameras = c.cameras;
      }
    } else if (chunk.type === 'splat') {
      // The worker counts whole 64-byte Gaussians of what has arrived; the GPU gets the texture.
      state.vertexCount = Math.floor((buffer.byteLength - remaining) / 4 / 16);
      if (remaining === 0) {
        state.texture = new Uint32Array(buffer);
        state.texwidth = chunk.texwidth;
        state.texheight = chunk.texheight;
      }
    }
  };
  // Small pieces, as a network stream would deliver them.
  let at = 0;
  const stream = new ReadableStream({
    pull(controller) {
      if (at >= bytes.length) return controller.close();
      const n = 1 + ((at * 7919) % 65521);
      controller.enqueue(bytes.subarray(at, at + n));
      at += n;
    },
  });
  await readChunks(stream.getReader(), [{ size: 8, type: 'magic' }], handler);
  return state;
}

// GLSL unpackHalf2x16 and texelFetch at the shader's addresses.
function halfToFloat(h) {
  const s = h & 0x8000 ? -1 : 1, e = (h >> 10) & 0x1f, m = h & 0x3ff;
  if (e === 0) return s * m * 2 ** -24;
  if (e === 31) return m ? NaN : s * Infinity;
  return s * (1 + m / 1024) * 2 ** (e - 15);
}
const unpack = (v) => [halfToFloat(v & 0xffff), halfToFloat(v >>> 16)];
function texel(state, index, k) {
  const x = ((index & 0x3ff) << 2) | k, y = index >>> 10;
  const base = (y * state.texwidth + x) * 4;
  return state.texture.subarray(base, base + 4);
}
const f32 = Math.fround;
const bits = new DataView(new ArrayBuffer(4));
const uintBitsToFloat = (u) => (bits.setUint32(0, u, true), bits.getFloat32(0, true));

// The vertex shader's position and temporal opacity at `time` (float32 arithmetic).
function evaluate(state, index, time) {
  const motion1 = texel(state, index, 3);
  const trbf = unpack(motion1[3]);
  const dt = f32(time - trbf[0]);
  const topacity = f32(Math.exp(f32(-1 * f32(f32(dt / trbf[1]) ** 2))));
  const motion0 = texel(state, index, 2);
  const static0 = texel(state, index, 0);
  const m0 = unpack(motion0[0]), m1 = unpack(motion0[1]), m2 = unpack(motion0[2]), m3 = unpack(motion0[3]), m4 = unpack(motion1[0]);
  const d1 = [m0[0], m0[1], m1[0]], d2 = [m1[1], m2[0], m2[1]], d3 = [m3[0], m3[1], m4[0]];
  const dt2 = f32(dt * dt), dt3 = f32(dt2 * dt);
  const position = [0, 1, 2].map((k) =>
    f32(uintBitsToFloat(static0[k]) + f32(f32(f32(d1[k] * dt) + f32(d2[k] * dt2)) + f32(d3[k] * dt3))));
  return { position, visible: topacity >= 0.02 };
}

// --- the check ------------------------------------------------------------------------
const bytes = new Uint8Array(fs.readFileSync(path.join(dir, manifest.splatv.file)));
const reference = JSON.parse(fs.readFileSync(path.join(dir, manifest.splatv.reference), 'utf8'));
const state = await loadSplatv(bytes);
const n = manifest.splatv.gaussians;
check(state.texture !== null, 'the splat chunk arrived complete');
check(state.texwidth === 4096 && state.texture.length === 4096 * state.texheight * 4,
      `texture ${state.texwidth}x${state.texheight} RGBA32UI matches the chunk size`);
check(state.vertexCount === state.texheight * 1024 && state.vertexCount >= n,
      `the viewer draws ${state.vertexCount} instances (${n} Gaussians + padding)`);
check(Array.isArray(state.cameras) && state.cameras.length > 0 && state.cameras.every((c) =>
      ['width', 'height', 'fx', 'fy', 'position', 'rotation'].every((k) => k in c)), 'cameras as the viewer reads them');
let padDrawn = 0;
for (let i = n; i < state.vertexCount; ++i) padDrawn += evaluate(state, i, 0).visible || evaluate(state, i, 1).visible ? 1 : 0;
check(padDrawn === 0, `padding instances are never drawn (${padDrawn} visible)`);

const report = reference.report;
const extent = report.scene_extent;
let sumSq = 0, count = 0;
for (const frame of reference.frames) {
  let frameSq = 0, worst = 0;
  for (let i = 0; i < n; ++i) {
    const p = evaluate(state, i, frame.u).position;
    let d2 = 0;
    for (let k = 0; k < 3; ++k) d2 += (p[k] - frame.positions[i * 3 + k]) ** 2;
    frameSq += d2;
    worst = Math.max(worst, Math.sqrt(d2));
  }
  sumSq += frameSq;
  count += n;
  const rms = Math.sqrt(frameSq / n);
  console.log(`u=${frame.u}: position RMS ${rms.toExponential(3)} (${(100 * rms / extent).toFixed(4)}% of extent), max ${worst.toExponential(3)}`);
  // u = 0 and 1 are sample times of the fit; the others fall between samples.
  check(rms <= 2.0 * report.position_rms + 1e-7, `u=${frame.u}: RMS ${rms.toExponential(3)} <= 2 x reported ${report.position_rms.toExponential(3)}`);
  check(worst <= 2.0 * report.position_max_relative * extent + 1e-6, `u=${frame.u}: max error within 2 x the reported maximum`);
}
const overall = Math.sqrt(sumSq / count);
console.log(`reported fit: ${JSON.stringify(report)}`);
check(overall <= 1.5 * report.position_rms + 1e-7, `overall RMS ${overall.toExponential(3)} agrees with the report`);
finish();
