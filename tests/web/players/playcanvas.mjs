// Shows one of our splat files in the unmodified PlayCanvas engine (npm playcanvas), under the
// fixture's camera: a .glb through the engine's glTF container loader (its KHR_gaussian_splatting
// extension), a .ply through its gsplat loader; with ?kernel=3dgs through 3DGS's kernel (its
// documented splat shader hooks, set by samples/web/playcanvas_3dgs.mjs). Used by
// tests/web/player_render.mjs.
import * as pc from 'playcanvas';
import { useTrainingKernel } from '/playcanvas_3dgs.mjs';
import { expose, fixtureCamera, params, rendererName } from './page_common.mjs';

const canvas = document.getElementById('view');
const status = document.getElementById('status');

function load(app, url, type) {
  return new Promise((resolve, reject) => {
    const asset = new pc.Asset(url, type, { url });
    asset.once('load', () => resolve(asset));
    asset.once('error', (e) => reject(new Error(`PlayCanvas could not load ${url}: ${e}`)));
    app.assets.add(asset);
    app.assets.load(asset);
  });
}

async function main() {
  const src = params.get('src');
  const view = await fixtureCamera();
  const { width, height, background } = view.camera;
  canvas.width = width;
  canvas.height = height;
  canvas.style.width = `${width}px`;
  canvas.style.height = `${height}px`;
  const app = new pc.Application(canvas, {
    graphicsDeviceOptions: { antialias: false, preserveDrawingBuffer: true, alpha: false, deviceTypes: ['webgl2'] },
  });
  app.setCanvasFillMode(pc.FILLMODE_NONE);
  app.setCanvasResolution(pc.RESOLUTION_FIXED, width, height);
  app.graphicsDevice.maxPixelRatio = 1;
  // ?kernel=3dgs draws splats as 3DGS training does (samples/web/playcanvas_3dgs.mjs: its 0.3 px²
  // blur, its Gaussian not lowered, its 1/255 cut, its 0.2 near-plane cull); ?kernel=PARTS
  // (comma-separated: dilation, falloff, extent, near) only some of these. Experiments:
  // ?dataformat=large|compact (the engine's work-buffer layout, app.scene.gsplat.dataFormat),
  // ?alphaclip=A (its alphaClipForward).
  let kernel = null;
  if (params.get('kernel')) {
    const all = ['dilation', 'falloff', 'extent', 'near'];
    const parts = params.get('kernel') === '3dgs' ? all : params.get('kernel').split(',');
    const unknown = parts.filter((p) => !all.includes(p));
    if (unknown.length) throw new Error(`unknown kernel part(s) ${unknown.join(', ')} (known: 3dgs, ${all.join(', ')})`);
    kernel = useTrainingKernel(app, Object.fromEntries(all.map((p) => [p, parts.includes(p)])));
  }
  if (params.get('dataformat')) app.scene.gsplat.dataFormat = params.get('dataformat');
  if (params.get('alphaclip')) app.scene.gsplat.alphaClipForward = parseFloat(params.get('alphaclip'));

  const camera = new pc.Entity('camera');
  const bg = background || [0, 0, 0];
  camera.addComponent('camera', {
    clearColor: new pc.Color(bg[0], bg[1], bg[2], 1),
    nearClip: view.near,
    farClip: view.far,
    fov: (view.fovY * 180) / Math.PI,
    toneMapping: pc.TONEMAP_NONE,      // splat colours pass through unchanged
    gammaCorrection: pc.GAMMA_SRGB,    // (they are sRGB values already)
  });
  // The fixture's intrinsics, principal point included (PlayCanvas: column-major Mat4.data).
  camera.camera.calculateProjection = (matrix) => matrix.data.set(view.projection);
  camera.setPosition(...view.position);
  camera.lookAt(new pc.Vec3(...view.target), new pc.Vec3(...view.up));
  app.root.addChild(camera);

  status.textContent = `loading ${src}`;
  const isGlb = /\.glb$/i.test(src);
  const asset = await load(app, src, isGlb ? 'container' : 'gsplat');
  let entity, resources;
  if (isGlb) {
    entity = asset.resource.instantiateRenderEntity();
    resources = (asset.resource.gsplats || []).map((a) => a.resource);
  } else {
    entity = new pc.Entity('splats');
    entity.addComponent('gsplat', { asset });
    resources = [asset.resource];
  }
  if (params.get('turn') === 'x180') {
    const holder = new pc.Entity('turn');
    holder.setLocalEulerAngles(180, 0, 0);
    holder.addChild(entity);
    entity = holder;
  }
  app.root.addChild(entity);
  app.start();
  status.textContent = '';
  return {
    player: `PlayCanvas ${pc.version}`,
    kernel,
    renderer: rendererName(app.graphicsDevice.gl),
    splatResources: resources.length,
    splats: resources.reduce((n, r) => n + (r?.numSplats || 0), 0),
    stop: () => { app.autoRender = false; },
  };
}

expose(canvas, main());
