// Runs the Khronos glTF-Validator (npm gltf-validator) on every glTF the fixture wrote:
// 0 errors and 0 warnings are required. Only MESH_PRIMITIVE_INVALID_ATTRIBUTE is ignored:
// the validator reports it for every KHR_gaussian_splatting:* attribute (validator issue
// #252). Infos and hints (e.g. UNSUPPORTED_EXTENSION for ours) are printed, not counted.
// Usage: node gltf_validator.mjs FIXTURE_DIR
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { check, finish, missing, readManifest } from './common.mjs';

const dir = path.resolve(process.argv[2] || '.');
const manifest = readManifest(dir);
let validator;
try {
  validator = createRequire(import.meta.url)('gltf-validator');
} catch {
  missing('npm package gltf-validator is missing: run tests/web/install.sh');
}
console.log(`glTF-Validator ${validator.version()}`);

const files = [...manifest.validator, manifest.letter_f.glb];
if (manifest.garden) files.push(manifest.garden.glb);
for (const name of files) {
  const file = path.join(dir, name);
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    maxIssues: 0,
    ignoredIssues: ['MESH_PRIMITIVE_INVALID_ATTRIBUTE'],
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
          err ? reject(err.toString()) : resolve(new Uint8Array(data)));
      }),
  });
  const { numErrors, numWarnings, numInfos, numHints, messages } = report.issues;
  const other = [...new Set(messages.filter((m) => m.severity > 1).map((m) => m.code))];
  for (const m of messages.filter((m) => m.severity <= 1)) console.log(`  ${name}: ${m.code} ${m.pointer || ''} ${m.message}`);
  check(numErrors === 0 && numWarnings === 0,
        `${name}: ${numErrors} errors, ${numWarnings} warnings (${numInfos} infos, ${numHints} hints: ${other.join(', ') || '-'}); ` +
        `extensions used: ${(report.info && report.info.extensionsUsed || []).join(', ')}`);
}

// Negative control: the same validator run must see a real defect (POSITION max off by one).
{
  const bytes = new Uint8Array(fs.readFileSync(path.join(dir, manifest.letter_f.glb)));
  const view = new DataView(bytes.buffer, bytes.byteOffset);
  const length = view.getUint32(12, true);
  const doc = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + length)));
  const position = doc.meshes[0].primitives[0].attributes.POSITION;
  doc.accessors[position].max[0] += 1;
  let text = JSON.stringify(doc);
  while (text.length % 4) text += ' ';
  const json = new TextEncoder().encode(text);
  const bin = bytes.subarray(20 + length);
  const out = new Uint8Array(20 + json.length + bin.length);
  const w = new DataView(out.buffer);
  w.setUint32(0, 0x46546c67, true), w.setUint32(4, 2, true), w.setUint32(8, out.length, true);
  w.setUint32(12, json.length, true), w.setUint32(16, 0x4e4f534a, true);
  out.set(json, 20);
  out.set(bin, 20 + json.length);
  const report = await validator.validateBytes(out, { maxIssues: 0, ignoredIssues: ['MESH_PRIMITIVE_INVALID_ATTRIBUTE'] });
  const codes = report.issues.messages.filter((m) => m.severity === 0).map((m) => m.code);
  check(codes.includes('ACCESSOR_MAX_MISMATCH'), `negative control: a forged POSITION max is reported (${codes.join(', ')})`);
}
finish();
