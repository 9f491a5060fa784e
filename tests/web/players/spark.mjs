// Shows one of our splat files in unmodified three.js (npm three) with Spark (npm
// @sparkjsdev/spark, default settings), under the fixture's camera. Spark reads .ply, .spz,
// .splat, .ksplat and SOG, not glTF. Used by tests/web/player_render.mjs.
import * as THREE from 'three';
import { SparkRenderer, SplatMesh } from '@sparkjsdev/spark';
import { expose, fixtureCamera, params, rendererName } from './page_common.mjs';

const canvas = document.getElementById('view');
const status = document.getElementById('status');

async function main() {
  const src = params.get('src');
  const view = await fixtureCamera();
  const { width, height, background } = view.camera;
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true, alpha: false });
  renderer.setPixelRatio(1);
  renderer.setSize(width, height);
  const bg = background || [0, 0, 0];
  renderer.setClearColor(new THREE.Color().setRGB(bg[0], bg[1], bg[2], THREE.SRGBColorSpace), 1);

  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera((view.fovY * 180) / Math.PI, width / height, view.near, view.far);
  camera.position.set(...view.position);
  camera.up.set(...view.up);
  camera.lookAt(...view.target);
  // The fixture's intrinsics, principal point included (three.js: column-major fromArray).
  camera.projectionMatrix.fromArray(view.projection);
  camera.projectionMatrixInverse.copy(camera.projectionMatrix).invert();
  camera.updateProjectionMatrix = () => {};  // keep it: nothing may recompute it from fov

  // Settings other than Spark's defaults only for experiments (JSON in ?spark= and ?mesh=).
  const spark = new SparkRenderer({ renderer, ...JSON.parse(params.get('spark') || '{}') });
  scene.add(spark);
  status.textContent = `loading ${src}`;
  const t0 = performance.now();
  const splats = new SplatMesh({ url: src, ...JSON.parse(params.get('mesh') || '{}') });
  await splats.initialized;
  const loadSeconds = (performance.now() - t0) / 1000;
  if (params.get('turn') === 'x180') splats.quaternion.set(1, 0, 0, 0);
  scene.add(splats);
  renderer.setAnimationLoop(() => renderer.render(scene, camera));
  status.textContent = '';
  return {
    player: `three.js r${THREE.REVISION} + Spark`,
    renderer: rendererName(renderer.getContext()),
    splats: splats.packedSplats?.numSplats ?? splats.extSplats?.numSplats ?? -1,
    loadSeconds,
    stop: () => renderer.setAnimationLoop(null),
  };
}

// Spark draws a frame of the lego in seconds on SwiftShader (it regenerates and re-sorts its
// splats every frame); its sort finishes within a frame, so two frames per check suffice.
expose(canvas, main(), 2);
