// Makes the unmodified PlayCanvas engine (2.23, WebGL2) draw Gaussian splats as 3DGS training
// draws them, through its public shader-chunk hooks for splats (gsplatModifyVS and
// gsplatModifyPS on the scene-wide material app.scene.gsplat.material; no engine file changed).
//
// PlayCanvas's own kernel differs from 3DGS's (and atex's) in three ways:
//   dilation  it adds 0.3 to a 2-D covariance measured in half pixels (its focal length is
//             viewport × P00, twice the pixel focal length): 0.075 px², where 3DGS adds 0.3 px²;
//   falloff   its Gaussian is lowered by e^-4 and rescaled, (e^-4A - e^-4) / (1 - e^-4), so that it
//             reaches zero at its cut (A = 1 at the quad's edge);
//   extent    its quad ends at 2√2 σ (where 3DGS's Gaussian is still e^-4 = 0.018), where 3DGS
//             keeps every sample with opacity × Gaussian >= 1/255 (out to 3.33 σ when opaque).
//   near      it culls only splats behind the camera and clamps the depth of those in front of its
//             near clip onto it, so splats between the camera and its near plane are drawn, where
//             3DGS culls every splat whose centre is nearer than 0.2 (its near plane): a real
//             capture's held-out cameras stand among such untrained splats (Panoptic: a dark haze)
// The hooks below undo each (options choose which, for measuring them one by one):
//   dilation  modifySplatRotationScale adds, in 3-D, the covariance whose projection is the
//             missing blur: s² along the camera's right and up axes projects (the projection is
//             linear in the covariance) to exactly s² J² in screen space, whatever the splat's
//             shape; the sum is turned back into a rotation and scales (a 3×3 eigen-decomposition)
//   extent    the same hook also scales the whole splat by k = sqrt(ln 255 / 4) ≈ 1.18, so the
//             engine's quad reaches 3.33 σ of the splat as 3DGS sees it (blur included)
//   falloff   modifySplatColor (fragment) recovers the opacity from the engine's alpha (which it
//             documents as falloff × opacity), then applies 3DGS's exp(-½ d²/σ²) (in the quad's
//             coordinate, exp(-4 k² A)), min(0.99, ·) and the 1/255 cut.
//   near      modifySplatColor (vertex stage) sets the opacity of a splat whose centre is nearer
//             than 0.2 along the camera's axis to 0, which the engine's alpha clip then drops.
// Limits: GLSL (WebGL2) only; unified splat rendering (the engine's default), where the hooks see
// world-space splats; a camera drawing the whole canvas (the engine's uScreenSize gives the pixel
// focal length); perspective cameras.
//
// Usage: import { useTrainingKernel } from './playcanvas_3dgs.mjs';
//        useTrainingKernel(app);   // once, after creating the pc.Application

// The engine's constants (PlayCanvas 2.23 gsplatCornerVS / gsplatPS).
const ENGINE_BLUR_HALF_PX2 = 0.3;  // added to the 2-D covariance in half-pixel units
const TRAINING_BLUR_PX2 = 0.3;     // 3DGS's low-pass (atex: kCov2dBlur)
const ALPHA_CUT = 1 / 255;         // 3DGS's sample cut (atex: kMinSplatAlpha)
const MAX_ALPHA = 0.99;            // 3DGS's alpha clamp (atex: kMaxSplatAlpha)
const NEAR_PLANE = 0.2;            // 3DGS's near-plane cull, scene units (atex: RenderSettings::near_plane)

// Vertex-stage chunk. `extraHalfPx2`: the blur to add in the engine's half-pixel units (0: none);
// `k2`: the square of the splat's enlargement (1: none); `near`: the cull distance (0: none).
function vertexChunk(extraHalfPx2, k2, near) {
  return /* glsl */ `
uniform mat4 matrix_viewInverse;     // the camera's pose in the world (engine-provided)
uniform mat4 matrix_viewProjection;  // projection × view (engine-provided)
uniform vec4 uScreenSize;            // width, height, 1/width, 1/height (engine-provided)

void modifySplatCenter(inout vec3 center) {}
void modifySplatColor(vec3 center, inout vec4 color) {
  // The camera looks along -z of its pose: the depth of the centre is along -matrix_viewInverse[2].
  float depth = dot(matrix_viewInverse[3].xyz - center, matrix_viewInverse[2].xyz);
  if (depth < ${near.toFixed(9)}) color.a = 0.0;
}

// One Jacobi rotation of the symmetric a, zeroing a[p][q]; v collects the rotations.
void atexJacobiRotate(inout mat3 a, inout mat3 v, int p, int q) {
  float apq = a[q][p];
  if (abs(apq) <= 1e-30) return;
  float theta = (a[q][q] - a[p][p]) / (2.0 * apq);
  float t = (theta >= 0.0 ? 1.0 : -1.0) / (abs(theta) + sqrt(theta * theta + 1.0));
  float c = inversesqrt(t * t + 1.0);
  float s = t * c;
  mat3 r = mat3(1.0);
  r[p][p] = c;
  r[q][q] = c;
  r[q][p] = s;   // row p, column q
  r[p][q] = -s;  // row q, column p
  a = transpose(r) * a * r;
  v = v * r;
}

// The unit quaternion (x, y, z, w) of the rotation matrix m (columns: the rotated axes).
vec4 atexQuatFromMat3(mat3 m) {
  float m00 = m[0][0], m11 = m[1][1], m22 = m[2][2];
  float trace = m00 + m11 + m22;
  vec4 q;
  if (trace > 0.0) {
    float s = 2.0 * sqrt(trace + 1.0);
    q = vec4((m[1][2] - m[2][1]) / s, (m[2][0] - m[0][2]) / s, (m[0][1] - m[1][0]) / s, 0.25 * s);
  } else if (m00 > m11 && m00 > m22) {
    float s = 2.0 * sqrt(1.0 + m00 - m11 - m22);
    q = vec4(0.25 * s, (m[1][0] + m[0][1]) / s, (m[2][0] + m[0][2]) / s, (m[1][2] - m[2][1]) / s);
  } else if (m11 > m22) {
    float s = 2.0 * sqrt(1.0 + m11 - m00 - m22);
    q = vec4((m[1][0] + m[0][1]) / s, 0.25 * s, (m[2][1] + m[1][2]) / s, (m[2][0] - m[0][2]) / s);
  } else {
    float s = 2.0 * sqrt(1.0 + m22 - m00 - m11);
    q = vec4((m[2][0] + m[0][2]) / s, (m[2][1] + m[1][2]) / s, 0.25 * s, (m[0][1] - m[1][0]) / s);
  }
  return normalize(q);
}

void modifySplatRotationScale(vec3 originalCenter, vec3 modifiedCenter, inout vec4 rotation, inout vec3 scale) {
  // The splat's covariance R S² Rᵀ (rotation is (x, y, z, w)).
  vec4 q = normalize(rotation);
  float x = q.x, y = q.y, z = q.z, w = q.w;
  mat3 r = mat3(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y),
                2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x),
                2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y));
  mat3 cov = r * mat3(scale.x * scale.x, 0.0, 0.0, 0.0, scale.y * scale.y, 0.0, 0.0, 0.0, scale.z * scale.z) * transpose(r);
  cov *= ${k2.toFixed(9)};
  // The blur, as a covariance in the plane of the camera's right and up axes: projected with the
  // engine's Jacobian (focal f = viewport × P, in half pixels, over the depth d) it adds
  // f²/d² × s² = the wanted blur on the screen's diagonal and nothing off it.
  vec3 right = matrix_viewInverse[0].xyz, up = matrix_viewInverse[1].xyz;
  float depth = dot(modifiedCenter - matrix_viewInverse[3].xyz, matrix_viewInverse[2].xyz);
  vec2 focal = uScreenSize.xy * vec2((matrix_viewProjection * vec4(right, 0.0)).x,
                                     (matrix_viewProjection * vec4(up, 0.0)).y);
  vec2 blur = ${extraHalfPx2.toFixed(9)} * depth * depth / (focal * focal);
  cov += blur.x * outerProduct(right, right) + blur.y * outerProduct(up, up);
  // Back to a rotation and scales: the eigenvectors and the square roots of the eigenvalues.
  mat3 v = mat3(1.0);
  for (int sweep = 0; sweep < 6; ++sweep) {
    atexJacobiRotate(cov, v, 0, 1);
    atexJacobiRotate(cov, v, 0, 2);
    atexJacobiRotate(cov, v, 1, 2);
  }
  scale = sqrt(max(vec3(cov[0][0], cov[1][1], cov[2][2]), vec3(0.0)));
  rotation = atexQuatFromMat3(v);
}
`;
}

// Fragment-stage chunk: 3DGS's Gaussian instead of the engine's lowered one. `k2` as above.
function fragmentChunk(k2) {
  return /* glsl */ `
void modifySplatColor(vec2 gaussianUV, inout vec4 color) {
  float a = dot(gaussianUV, gaussianUV);
  // The engine's alpha is its falloff (e^-4a - e^-4) / (1 - e^-4) times the splat's opacity, and
  // it discards the fragment before this hook when that is below its alphaClipForward (> 0).
  float engineFalloff = (exp(-4.0 * a) - exp(-4.0)) / (1.0 - exp(-4.0));
  float opacity = color.a / engineFalloff;
  float alpha = min(${MAX_ALPHA.toFixed(6)}, opacity * exp(-4.0 * ${k2.toFixed(9)} * a));
  if (alpha < ${ALPHA_CUT.toFixed(9)}) discard;
  color.a = alpha;
}
`;
}

// Sets the hooks on the scene-wide splat material of `app` (a pc.AppBase on WebGL2; throws on
// WebGPU, whose WGSL chunks these are not).
// Options (all true by default; false keeps the engine's behaviour for that part):
//   dilation  3DGS's 0.3 px² screen-space blur instead of the engine's 0.075 px²
//   falloff   3DGS's Gaussian instead of the engine's lowered one
//   extent    the quad reaches 3DGS's 1/255 cut (needs falloff)
//   near      splats nearer than 3DGS's 0.2 near plane are culled
// Returns the settings applied.
export function useTrainingKernel(app, { dilation = true, falloff = true, extent = true, near = true } = {}) {
  if (extent && !falloff) throw new Error('useTrainingKernel: extent needs falloff');
  if (app.graphicsDevice.isWebGPU) throw new Error('useTrainingKernel: WebGL2 only (these hooks are GLSL)');
  const k2 = extent ? Math.log(1 / ALPHA_CUT) / 4 : 1;
  // Wanted in half pixels: k² × (the splat + 4 × 0.3); the engine then adds its 0.3 itself.
  const extraHalfPx2 = dilation ? k2 * 4 * TRAINING_BLUR_PX2 - ENGINE_BLUR_HALF_PX2
                                : (k2 - 1) * ENGINE_BLUR_HALF_PX2;
  const material = app.scene.gsplat.material;
  const chunks = material.getShaderChunks('glsl');
  if (dilation || extent || near) chunks.set('gsplatModifyVS', vertexChunk(extraHalfPx2, k2, near ? NEAR_PLANE : 0));
  else chunks.delete('gsplatModifyVS');
  if (falloff) chunks.set('gsplatModifyPS', fragmentChunk(k2));
  else chunks.delete('gsplatModifyPS');
  material.update();
  return { dilation, falloff, extent, near, k2, extraHalfPx2 };
}
