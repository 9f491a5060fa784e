// Shared bits of the node checks in tests/web.
import fs from 'node:fs';
import path from 'node:path';

// A missing prerequisite fails in CI (ATEX_REQUIRE_DATA=1) and skips (exit 77) elsewhere.
export function missing(what) {
  if (process.env.ATEX_REQUIRE_DATA === '1') {
    console.error(`FAIL: ${what}`);
    process.exit(1);
  }
  console.error(`SKIP: ${what}`);
  process.exit(77);
}

export function readManifest(dir) {
  const file = path.join(dir, 'manifest.json');
  if (!fs.existsSync(file)) missing(`${file} is missing: the web_fixture test writes it`);
  return JSON.parse(fs.readFileSync(file, 'utf8'));
}

// Records a check; the process exits non-zero at the end if any failed.
const failures = [];
export function check(ok, message) {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${message}`);
  if (!ok) failures.push(message);
}
export function finish() {
  if (failures.length) {
    console.error(`${failures.length} check(s) failed`);
    process.exit(1);
  }
  console.log('all checks passed');
}
