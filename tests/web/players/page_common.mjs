// What the player pages of tests/web/players share: the page's parameters, the camera of a
// fixture (camera.json) as a pose and a projection in the player's world (right-handed, +y up,
// the camera looking along -z: glTF's, three.js's and PlayCanvas's convention alike), the wait
// for a picture that has stopped changing, and window.atexView for the test driver
// (tests/web/player_render.mjs reads window.atexView.canvas once window.atexView.ready resolves).
//
// Page parameters:
//   src=/data/FILE           the splat file the player loads
//   camera=/data/CAM.json    the fixture's camera (width, height, fx, fy, cx, cy, background, pose)
//   turn=x180                turn the loaded splats 180 degrees about x first: the 3DGS PLY
//                            convention (y down, z forward) shown in a y-up world
//   rotation=/data/FILE.glb  for a pose given in the asset's own world (opencv_world_to_camera):
//                            the glTF node rotation that takes that world to the y-up world

export const params = new URLSearchParams(location.search);

// Rotates v by the unit quaternion q = (x, y, z, w): q v q*.
function rotate(q, v) {
  const [x, y, z, w] = q;
  const t = [2 * (y * v[2] - z * v[1]), 2 * (z * v[0] - x * v[2]), 2 * (x * v[1] - y * v[0])];
  return [v[0] + w * t[0] + (y * t[2] - z * t[1]), v[1] + w * t[1] + (z * t[0] - x * t[2]),
          v[2] + w * t[2] + (x * t[1] - y * t[0])];
}

// The node rotation (x, y, z, w) of a .glb's splat node, read from its JSON chunk.
async function nodeRotation(url) {
  const bytes = new Uint8Array(await (await fetch(url)).arrayBuffer());
  const view = new DataView(bytes.buffer);
  if (view.getUint32(0, true) !== 0x46546c67) throw new Error(`${url} is not a .glb`);
  const json = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + view.getUint32(12, true))));
  const node = (json.nodes || []).find((n) => n.mesh !== undefined) || {};
  return node.rotation || [0, 0, 0, 1];
}

// Reads the fixture's camera; resolves to { camera, position, target, up, projection, ... }
// in the player's world. `projection` is column-major (OpenGL clip space, depth -1..1) with
// the principal point of the OpenCV intrinsics. The near plane is the camera's `near` where the
// fixture states it (our renderer's, culling the splats in front of it as 3DGS does), else `near`.
export async function fixtureCamera(defaultNear = 0.01, far = 1000) {
  const camera = await (await fetch(params.get('camera'))).json();
  const near = camera.near ?? defaultNear;
  let position, target, up;
  if (camera.pose.gltf) {
    ({ position, target, up } = camera.pose.gltf);
  } else {
    // OpenCV world-to-camera [W | T]; the rows of W are the camera's axes in the asset's world.
    // Centre -W^T T, forward W^T e_z, up -W^T e_y, each turned by the glTF node rotation.
    const m = camera.pose.opencv_world_to_camera;
    const row = (r) => [m[r * 4], m[r * 4 + 1], m[r * 4 + 2]];
    const T = [m[3], m[7], m[11]];
    const centre = [0, 1, 2].map((c) => -(row(0)[c] * T[0] + row(1)[c] * T[1] + row(2)[c] * T[2]));
    const q = params.get('rotation') ? await nodeRotation(params.get('rotation')) : [0, 0, 0, 1];
    position = rotate(q, centre);
    target = rotate(q, centre.map((v, c) => v + row(2)[c]));
    up = rotate(q, row(1).map((v) => -v));
  }
  const { width: w, height: h, fx, fy, cx, cy } = camera;
  // x_clip = 2fx/w x + (1 - 2cx/w) z, y_clip = 2fy/h y + (2cy/h - 1) z (camera looks along -z,
  // image rows grow downwards), the usual OpenGL depth row.
  const projection = [2 * fx / w, 0, 0, 0,
                      0, 2 * fy / h, 0, 0,
                      1 - 2 * cx / w, 2 * cy / h - 1, -(far + near) / (far - near), -1,
                      0, 0, -2 * far * near / (far - near), 0];
  return { camera, position, target, up, projection, near, far, fovY: 2 * Math.atan(h / (2 * fy)) };
}

// The WebGL renderer string of a context (SwiftShader in the tests).
export function rendererName(gl) {
  const ext = gl.getExtension('WEBGL_debug_renderer_info');
  return gl.getParameter(ext ? ext.UNMASKED_RENDERER_WEBGL : gl.RENDERER);
}

// Resolves once the canvas shows the same, non-empty picture three checks in a row,
// `framesPerCheck` animation frames apart (players sort splats in workers, so the first frames
// differ).
export async function settle(canvas, framesPerCheck = 5, maxChecks = 400) {
  const copy = new OffscreenCanvas(canvas.width, canvas.height);
  const g = copy.getContext('2d', { willReadFrequently: true });
  const frame = () => new Promise((r) => requestAnimationFrame(() => r()));
  let previous = null, stable = 0;
  const t0 = performance.now(), times = [];
  for (let i = 0; i < maxChecks; ++i) {
    for (let k = 0; k < framesPerCheck; ++k) await frame();
    times.push(Math.round(performance.now() - t0));
    g.clearRect(0, 0, copy.width, copy.height);
    g.drawImage(canvas, 0, 0);
    const px = g.getImageData(0, 0, copy.width, copy.height).data;
    let drawn = 0;
    for (let j = 0; j < px.length; j += 4) drawn += px[j] | px[j + 1] | px[j + 2] ? 1 : 0;
    const same = previous && previous.every((v, j) => v === px[j]);
    stable = same && drawn > 0 ? stable + 1 : 0;
    if (stable >= 3) return { frames: (i + 1) * framesPerCheck, drawnPixels: drawn, checkTimesMs: times };
    previous = px;
  }
  throw new Error('the picture never settled');
}

// Publishes the page to the driver: `work` resolves to the info the driver logs, and may hold
// stop(), called once the picture has settled (a slow player then stops drawing, so the
// driver's comparisons in the page do not wait behind its frames; the canvas keeps the picture).
export function expose(canvas, work, framesPerCheck = 5) {
  const status = document.getElementById('status');
  window.atexView = {
    canvas,
    ready: work.then(async ({ stop, ...info }) => {
      const settled = await settle(canvas, framesPerCheck);
      if (stop) stop();
      return { ...info, ...settled };
    }).catch((e) => {
      if (status) status.textContent = `error: ${e.message}`;
      throw e;
    }),
  };
}
