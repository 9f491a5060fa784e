// Shows an atex .glb (KHR_gaussian_splatting) in unmodified Babylon.js.
// The scene is right-handed (glTF's convention), so no handedness flip is applied and a
// camera stated in glTF coordinates is used as is. window.atexViewer exposes the engine
// and a `ready` promise for tests/web/babylon_render.mjs (also as window.atexView).
import { Engine } from '@babylonjs/core/Engines/engine.js';
import { Scene } from '@babylonjs/core/scene.js';
import { Color4 } from '@babylonjs/core/Maths/math.color.js';
import { Matrix, Vector3, Quaternion } from '@babylonjs/core/Maths/math.vector.js';
import { TargetCamera } from '@babylonjs/core/Cameras/targetCamera.js';
import { ArcRotateCamera } from '@babylonjs/core/Cameras/arcRotateCamera.js';
import { ImportMeshAsync } from '@babylonjs/core/Loading/sceneLoader.js';
import { MeshoptCompression } from '@babylonjs/core/Meshes/Compression/meshoptCompression.js';
import { GaussianSplattingMaterial } from '@babylonjs/core/Materials/GaussianSplatting/gaussianSplattingMaterial.js';
import '@babylonjs/loaders/glTF/index.js';

const params = new URLSearchParams(location.search);
const status = document.getElementById('status');
const canvas = document.getElementById('view');
const say = (text) => { status.textContent = text; };

// EXT_meshopt_compression's decoder, from the npm package instead of Babylon's CDN.
MeshoptCompression.Configuration.decoder.url = '/node_modules/meshoptimizer/meshopt_decoder.cjs';

// glTF node rotation (x, y, z, w) of the file, read from its JSON chunk.
async function nodeRotation(url) {
  const bytes = new Uint8Array(await (await fetch(url)).arrayBuffer());
  const view = new DataView(bytes.buffer);
  let json;
  if (view.getUint32(0, true) === 0x46546c67) {
    const length = view.getUint32(12, true);
    json = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + length)));
  } else {
    json = JSON.parse(new TextDecoder().decode(bytes));
  }
  const node = (json.nodes || []).find((n) => n.mesh !== undefined) || {};
  return node.rotation || [0, 0, 0, 1];
}

// OpenCV intrinsics as a right-handed GL projection (principal point included).
function projection(cam, near, far) {
  const m = Matrix.PerspectiveFovRH(2 * Math.atan(cam.height / (2 * cam.fy)), cam.width / cam.height, near, far,
                                     camera_engine.isNDCHalfZRange);
  const a = m.asArray().slice();
  a[0] = (2 * cam.fx) / cam.width;
  a[5] = (2 * cam.fy) / cam.height;
  // Clip x = 2fx/w x + (1 - 2cx/w) z and clip y = 2fy/h y + (2cy/h - 1) z for a camera looking
  // along -z (image rows grow downwards); the x term's sign was reversed until a Panoptic camera
  // (cx 5.7 px left of the centre) showed an 11 px shift.
  a[8] = 1 - (2 * cam.cx) / cam.width;
  a[9] = (2 * cam.cy) / cam.height - 1;
  return Matrix.FromArray(a);
}

let camera_engine;

async function main() {
  const src = params.get('src');
  if (!src) {
    say('add ?src=/data/<file>.glb to the address');
    return;
  }
  const cameraUrl = params.get('camera');
  const fixed = cameraUrl ? await (await fetch(cameraUrl)).json() : null;
  if (fixed) {
    canvas.style.width = `${fixed.width}px`;
    canvas.style.height = `${fixed.height}px`;
  }
  // ?kernel=K sets Babylon's screen-space blur (GaussianSplattingMaterial.KernelSize, default 0.3).
  // Babylon adds it to the covariance of splats of twice the glTF's scales (four times the
  // variance), so its default is 0.075 px² in 3DGS's terms; kernel=1.2 gives 3DGS's 0.3 px²
  // (BENCHMARKS.md, "A trained asset in Babylon.js").
  if (params.get('kernel')) GaussianSplattingMaterial.KernelSize = parseFloat(params.get('kernel'));
  const engine = new Engine(canvas, false, { preserveDrawingBuffer: true, antialias: false, stencil: false }, false);
  camera_engine = engine;
  engine.setHardwareScalingLevel(1);
  const scene = new Scene(engine);
  scene.useRightHandedSystem = true;
  const bg = fixed?.background || [0, 0, 0];
  scene.clearColor = new Color4(bg[0], bg[1], bg[2], 1);

  let camera;
  if (fixed) {
    camera = new TargetCamera('atex', Vector3.Zero(), scene);
    let position, target, up;
    if (fixed.pose.gltf) {
      ({ position, target, up } = fixed.pose.gltf);
    } else {
      // OpenCV world-to-camera [W | T] in the asset's world; the file's node rotation Q takes
      // the asset to glTF: centre Q(-W^T T), forward Q(W^T e_z), up -Q(W^T e_y).
      const m = fixed.pose.opencv_world_to_camera;
      const W = [0, 1, 2].map((r) => new Vector3(m[r * 4], m[r * 4 + 1], m[r * 4 + 2]));  // rows of W = camera axes in the world
      const T = [m[3], m[7], m[11]];
      const centre = W[0].scale(-T[0]).add(W[1].scale(-T[1])).add(W[2].scale(-T[2]));
      const q = fixed.pose.apply_node_rotation ? await nodeRotation(src) : [0, 0, 0, 1];
      const Q = new Quaternion(q[0], q[1], q[2], q[3]);
      const rotate = (v) => v.applyRotationQuaternion(Q);
      position = rotate(centre).asArray();
      target = rotate(centre.add(W[2])).asArray();
      up = rotate(W[1].scale(-1)).asArray();
    }
    camera.position = Vector3.FromArray(position);
    camera.upVector = Vector3.FromArray(up);
    camera.setTarget(Vector3.FromArray(target));
    camera.minZ = fixed.near ?? 0.01;  // the renderer's near plane where the camera file states it
    camera.maxZ = 1000;
    camera.freezeProjectionMatrix(projection(fixed, camera.minZ, camera.maxZ));
  } else {
    camera = new ArcRotateCamera('orbit', Math.PI / 2, Math.PI / 2.2, 3, Vector3.Zero(), scene);
    camera.minZ = 0.01;
    camera.wheelPrecision = 50;
    camera.attachControl(canvas, true);
  }
  scene.activeCamera = camera;

  say(`loading ${src}`);
  const result = await ImportMeshAsync(src, scene);
  const splats = result.meshes.filter((m) => m.getClassName && m.getClassName().includes('GaussianSplatting'));
  if (!fixed) {
    // Frame the splats.
    let min = new Vector3(Infinity, Infinity, Infinity), max = min.scale(-1);
    for (const m of result.meshes) {
      m.computeWorldMatrix(true);
      const b = m.getBoundingInfo?.().boundingBox;
      if (!b) continue;
      min = Vector3.Minimize(min, b.minimumWorld);
      max = Vector3.Maximize(max, b.maximumWorld);
    }
    if (Number.isFinite(min.x)) {
      camera.setTarget(min.add(max).scale(0.5));
      camera.radius = 1.5 * max.subtract(min).length();
    }
  }
  engine.runRenderLoop(() => scene.render());
  window.addEventListener('resize', () => engine.resize());
  say(`${src}: ${splats.length} splat mesh(es)`);
  return { engine, scene, camera, splats, fixed };
}

// Resolves once the picture stops changing (Babylon sorts splats in a worker).
async function settle(engine, maxFrames = 600) {
  const gl = engine._gl;
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
  const frame = () => new Promise((r) => engine.onEndFrameObservable.addOnce(() => r()));
  const read = () => {
    const px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    return px;
  };
  let previous = null, stable = 0;
  for (let i = 0; i < maxFrames; ++i) {
    for (let k = 0; k < 5; ++k) await frame();
    const px = read();
    let nonzero = 0;
    for (let j = 0; j < px.length; j += 4) nonzero += px[j] | px[j + 1] | px[j + 2] ? 1 : 0;
    const same = previous && previous.every((v, j) => v === px[j]);
    stable = same && nonzero > 0 ? stable + 1 : 0;
    if (stable >= 3) return { frames: (i + 1) * 5, drawnPixels: nonzero };
    previous = px;
  }
  throw new Error('the render never settled');
}

window.atexView = window.atexViewer = {
  canvas,
  ready: main().then(async (ctx) => {
    if (!ctx) return null;
    const info = await settle(ctx.engine);
    window.atexViewer.ctx = ctx;
    return { ...info, splatMeshes: ctx.splats.length, renderer: ctx.engine.getGlInfo().renderer };
  }).catch((e) => {
    say(`error: ${e.message}`);
    throw e;
  }),
};
