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

// The checks of a trained model's full-frame scene (a real capture: nearly every pixel is
// covered, so the foreground IoU and its upside-down/mirrored variants of the object scenes say
// little): PSNR against our render >= floor; the same picture against the reference with red and
// blue swapped must fail that floor (a wrong colour order cannot pass); the picture turned upside
// down or mirrored left-right must match clearly worse than as shown (a wrong axis or handedness
// cannot pass).
export const ORIENTATION_MARGIN_DB = 3;
export function checkFullFrame(label, stats, floor) {
  check(stats.psnr >= floor, `${label}: PSNR ${stats.psnr.toFixed(2)} dB against our render >= ${floor} dB`);
  check(stats.psnrRedBlueSwapped < floor,
        `${label}: with red and blue swapped the guard fails (${stats.psnrRedBlueSwapped.toFixed(2)} dB < ${floor} dB)`);
  checkOrientation(label, stats);
}
// The orientation guard alone (a player's default settings, where no PSNR floor applies).
export function checkOrientation(label, stats) {
  for (const [what, db] of [['upside down', stats.psnrUpsideDown], ['mirrored', stats.psnrMirrored]]) {
    check(db < stats.psnr - ORIENTATION_MARGIN_DB,
          `${label}: ${what} matches clearly worse (${db.toFixed(2)} dB < ${stats.psnr.toFixed(2)} - ${ORIENTATION_MARGIN_DB} dB)`);
  }
}
