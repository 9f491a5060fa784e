// Decodes an SPZ file with the reference SPZ library (npm @adobe/spz: the WASM
// build of github.com/nianticlabs/spz) and writes what it decoded as JSON, for
// converters/src/spz/spz_node_test.cc to compare with libatex's own decoder.
//
//   node decode_spz.mjs IN.spz OUT.json [--to RDF|RUB|UNSPECIFIED] [--stride K]
//
// OUT.json: {numPoints, shDegree, antialiased, shDim, stride, points: [{index,
//   position[3], scale[3] (log), rotation[4] (x, y, z, w), alpha (logit),
//   color[3] (SH DC), sh[shDim * 3] (coefficient-major, RGB innermost)}]}
// for every K-th Gaussian. Exit status 0 on success, 1 when decoding failed.
import fs from 'node:fs';
import createSpzModule from '@adobe/spz';

function usage(message) {
  process.stderr.write(`decode_spz.mjs: ${message}\n`);
  process.exit(2);
}

const args = process.argv.slice(2);
if (args.length < 2) usage('usage: node decode_spz.mjs IN.spz OUT.json [--to RDF|RUB|UNSPECIFIED] [--stride K]');
const [input, output] = args;
let to = 'UNSPECIFIED';
let stride = 1;
for (let i = 2; i < args.length; i += 2) {
  if (args[i] === '--to') to = args[i + 1];
  else if (args[i] === '--stride') stride = Math.max(1, parseInt(args[i + 1], 10));
  else usage(`unknown option ${args[i]}`);
}

// The library logs through Module.print (stdout); keep stdout/stderr clean of it.
const spz = await createSpzModule({ print: () => {}, printErr: () => {} });
if (!(to in spz.CoordinateSystem)) usage(`unknown coordinate system ${to}`);
const bytes = new Uint8Array(fs.readFileSync(input));
const cloud = spz.loadSpzFromBuffer(bytes, { to: spz.CoordinateSystem[to] });
if (!cloud || cloud.numPoints === 0) {
  process.stderr.write(`decode_spz.mjs: the reference decoder returned no Gaussians for ${input}\n`);
  process.exit(1);
}
const n = cloud.numPoints;
const shDim = n > 0 ? cloud.sh.length / (3 * n) : 0;
const pick = (array, i, width) => Array.from(array.subarray(i * width, (i + 1) * width));
const points = [];
for (let i = 0; i < n; i += stride) {
  points.push({
    index: i,
    position: pick(cloud.positions, i, 3),
    scale: pick(cloud.scales, i, 3),
    rotation: pick(cloud.rotations, i, 4),
    alpha: cloud.alphas[i],
    color: pick(cloud.colors, i, 3),
    sh: pick(cloud.sh, i, shDim * 3),
  });
}
fs.writeFileSync(output, JSON.stringify({
  numPoints: n, shDegree: cloud.shDegree, antialiased: cloud.antialiased, shDim, stride, points,
}));
