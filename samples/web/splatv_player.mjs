// A WebGL2 player for .splatv files (atex's splaTV export). Reads the file as splaTV's
// viewer does (magic 0x674b, JSON chunk list, RGBA32UI texture of 16 words per Gaussian),
// evaluates the motion per vertex, projects with the EWA splatting of 3DGS and blends
// back to front. Exposes window.atexView = { ready, canvas } for tests/web.
const params = new URLSearchParams(location.search);
const status = document.getElementById('status');
const canvas = document.getElementById('view');
const say = (text) => { status.textContent = text; };

const vertexShader = `#version 300 es
precision highp float;
precision highp int;
precision highp usampler2D;
uniform usampler2D u_splats;
uniform mat3 u_rotation;     // world -> camera (OpenCV axes: x right, y down, z forward)
uniform vec3 u_translation;
uniform vec4 u_intrinsics;   // fx, fy, cx, cy in pixels
uniform vec2 u_size;         // viewport in pixels
uniform float u_time;        // [0, 1]
in vec2 a_corner;            // quad corner in [-1, 1]^2
in uint a_index;             // Gaussian, in back-to-front order
out vec4 v_color;
out vec2 v_offset;           // pixels from the projected centre
out vec3 v_conic;            // inverse 2D covariance (a, b, c)

uvec4 word4(uint i, uint k) { return texelFetch(u_splats, ivec2(int(((i & 1023u) << 2) | k), int(i >> 10)), 0); }

void main() {
  gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // outside the clip volume unless drawn
  uvec4 s0 = word4(a_index, 0u), s1 = word4(a_index, 1u), m0 = word4(a_index, 2u), m1 = word4(a_index, 3u);
  vec2 trbf = unpackHalf2x16(m1.w);
  float dt = u_time - trbf.x;
  float fade = exp(-(dt / trbf.y) * (dt / trbf.y));
  if (!(fade >= 0.02)) return;
  vec2 a = unpackHalf2x16(m0.x), b = unpackHalf2x16(m0.y), c = unpackHalf2x16(m0.z), d = unpackHalf2x16(m0.w),
       e = unpackHalf2x16(m1.x);
  vec3 mean = uintBitsToFloat(s0.xyz) + vec3(a.x, a.y, b.x) * dt + vec3(b.y, c.x, c.y) * (dt * dt) +
              vec3(d.x, d.y, e.x) * (dt * dt * dt);
  vec4 q = normalize(vec4(unpackHalf2x16(s0.w), unpackHalf2x16(s1.x)) +
                     vec4(unpackHalf2x16(m1.y), unpackHalf2x16(m1.z)) * dt);  // (w, x, y, z)
  vec3 scale = vec3(unpackHalf2x16(s1.y), unpackHalf2x16(s1.z).x);
  vec3 t = u_rotation * mean + u_translation;
  if (t.z <= 0.01) return;
  float w = q.x, x = q.y, y = q.z, z = q.w;
  mat3 r = mat3(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y),
                2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x),
                2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y));  // columns = local axes
  mat3 m = u_rotation * r * mat3(scale.x, 0.0, 0.0, 0.0, scale.y, 0.0, 0.0, 0.0, scale.z);
  mat3 sigma = m * transpose(m);  // camera-space covariance
  float fx = u_intrinsics.x, fy = u_intrinsics.y;
  vec3 j0 = vec3(fx / t.z, 0.0, -fx * t.x / (t.z * t.z));
  vec3 j1 = vec3(0.0, fy / t.z, -fy * t.y / (t.z * t.z));
  float s00 = dot(j0, sigma * j0) + 0.3, s01 = dot(j0, sigma * j1), s11 = dot(j1, sigma * j1) + 0.3;
  float det = s00 * s11 - s01 * s01;
  if (det <= 0.0) return;
  float mid = 0.5 * (s00 + s11), disc = sqrt(max(0.1, mid * mid - det));
  float l1 = mid + disc, l2 = max(mid - disc, 0.01);
  vec2 axis = abs(s01) > 1e-9 ? normalize(vec2(s01, l1 - s00)) : (s00 >= s11 ? vec2(1.0, 0.0) : vec2(0.0, 1.0));
  vec2 offset = a_corner.x * 3.0 * sqrt(l1) * axis + a_corner.y * 3.0 * sqrt(l2) * vec2(-axis.y, axis.x);
  vec2 pixel = vec2(fx * t.x / t.z + u_intrinsics.z, fy * t.y / t.z + u_intrinsics.w) + offset;
  gl_Position = vec4(2.0 * pixel.x / u_size.x - 1.0, 1.0 - 2.0 * pixel.y / u_size.y, 0.0, 1.0);
  v_offset = offset;
  v_conic = vec3(s11, -s01, s00) / det;
  uint rgba = s1.w;
  v_color = vec4(float(rgba & 255u), float((rgba >> 8) & 255u), float((rgba >> 16) & 255u), float(rgba >> 24)) / 255.0;
  v_color.a *= fade;
}`;

const fragmentShader = `#version 300 es
precision highp float;
in vec4 v_color;
in vec2 v_offset;
in vec3 v_conic;
out vec4 color;
void main() {
  float power = -0.5 * (v_conic.x * v_offset.x * v_offset.x + v_conic.z * v_offset.y * v_offset.y) -
                v_conic.y * v_offset.x * v_offset.y;
  if (power > 0.0) discard;
  float alpha = min(0.99, v_color.a * exp(power));
  if (alpha < 1.0 / 255.0) discard;
  color = vec4(v_color.rgb * alpha, alpha);  // premultiplied, blended back to front
}`;

const halfToFloat = (h) => {
  const s = h & 0x8000 ? -1 : 1, e = (h >> 10) & 0x1f, m = h & 0x3ff;
  if (e === 0) return s * m * 2 ** -24;
  if (e === 31) return m ? NaN : s * Infinity;
  return s * (1 + m / 1024) * 2 ** (e - 15);
};

function parseSplatv(buffer) {
  const view = new DataView(buffer);
  if (buffer.byteLength < 8 || view.getUint32(0, true) !== 0x674b) throw new Error('not a .splatv file');
  const jsonLength = view.getUint32(4, true);
  const chunks = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 8, jsonLength)));
  let offset = 8 + jsonLength;
  for (const chunk of chunks) {
    if (chunk.type === 'splat') {
      if (offset + chunk.size > buffer.byteLength) throw new Error('truncated .splatv file');
      return { chunk, words: new Uint32Array(buffer.slice(offset, offset + chunk.size)) };
    }
    offset += chunk.size;
  }
  throw new Error('no splat chunk');
}

function compile(gl, type, source) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, source);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
  return shader;
}

async function main() {
  const src = params.get('src');
  if (!src) {
    say('add ?src=/data/<file>.splatv to the address');
    return null;
  }
  const { chunk, words } = parseSplatv(await (await fetch(src)).arrayBuffer());
  const count = words.length / 16;
  const cameras = chunk.cameras || [];
  const cam = structuredClone(cameras[Number(params.get('camera') || 0)] || cameras[0]);
  const fixed = params.get('fixed') === '1';
  if (fixed) {
    canvas.style.width = `${cam.width}px`;
    canvas.style.height = `${cam.height}px`;
    document.getElementById('bar').style.display = 'none';
    status.style.display = 'none';
  }
  const gl = canvas.getContext('webgl2', { antialias: false, alpha: false, preserveDrawingBuffer: true });
  if (!gl) throw new Error('WebGL2 is not available');
  const program = gl.createProgram();
  gl.attachShader(program, compile(gl, gl.VERTEX_SHADER, vertexShader));
  gl.attachShader(program, compile(gl, gl.FRAGMENT_SHADER, fragmentShader));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  gl.useProgram(program);
  const uniform = (name) => gl.getUniformLocation(program, name);

  const texture = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, texture);
  for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32UI, chunk.texwidth, chunk.texheight, 0, gl.RGBA_INTEGER, gl.UNSIGNED_INT, words);
  gl.uniform1i(uniform('u_splats'), 0);

  const quad = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, quad);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, 1, 1, -1, 1]), gl.STATIC_DRAW);
  const cornerLocation = gl.getAttribLocation(program, 'a_corner');
  gl.enableVertexAttribArray(cornerLocation);
  gl.vertexAttribPointer(cornerLocation, 2, gl.FLOAT, false, 0, 0);
  const order = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, order);
  const indexLocation = gl.getAttribLocation(program, 'a_index');
  gl.enableVertexAttribArray(indexLocation);
  gl.vertexAttribIPointer(indexLocation, 1, gl.UNSIGNED_INT, 0, 0);
  gl.vertexAttribDivisor(indexLocation, 1);
  gl.disable(gl.DEPTH_TEST);
  gl.enable(gl.BLEND);
  gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);

  // Static part of the motion for sorting on the CPU.
  const f32 = new Float32Array(words.buffer);
  const motion = new Float32Array(count * 11);  // x y z, d1 xyz, d2 xyz, trbf center, (unused)
  for (let i = 0; i < count; ++i) {
    const w = i * 16, o = i * 11;
    motion[o] = f32[w], motion[o + 1] = f32[w + 1], motion[o + 2] = f32[w + 2];
    const h = (k) => halfToFloat(k);
    motion[o + 3] = h(words[w + 8] & 0xffff), motion[o + 4] = h(words[w + 8] >>> 16), motion[o + 5] = h(words[w + 9] & 0xffff);
    motion[o + 6] = h(words[w + 9] >>> 16), motion[o + 7] = h(words[w + 10] & 0xffff), motion[o + 8] = h(words[w + 10] >>> 16);
    motion[o + 9] = h(words[w + 15] & 0xffff);
  }

  // Camera: OpenCV camera-to-world rotation (rows), centre; orbit around the scene centre.
  let rotation = cam.rotation.flat();  // c2w, row-major
  let centre = cam.position.slice();
  const target = [0, 0, 0];
  for (let i = 0; i < count; ++i) for (let k = 0; k < 3; ++k) target[k] += motion[i * 11 + k] / count;
  const dist = Math.hypot(centre[0] - target[0], centre[1] - target[1], centre[2] - target[2]);

  let time = params.has('t') ? Number(params.get('t')) : 0;
  let playing = !params.has('t');
  const slider = document.getElementById('time'), clock = document.getElementById('clock'), play = document.getElementById('play');
  play.onclick = () => { playing = !playing; play.textContent = playing ? 'pause' : 'play'; };
  slider.oninput = () => { time = slider.value / 1000; playing = false; play.textContent = 'play'; };
  let drag = null;
  canvas.addEventListener('pointerdown', (e) => { drag = [e.clientX, e.clientY]; });
  window.addEventListener('pointerup', () => { drag = null; });
  const rotateAbout = (axis, angle) => {  // rotate the camera around `target` about a world axis
    const [x, y, z] = axis, c = Math.cos(angle), s = Math.sin(angle), t = 1 - c;
    const r = [t * x * x + c, t * x * y - s * z, t * x * z + s * y, t * x * y + s * z, t * y * y + c, t * y * z - s * x,
               t * x * z - s * y, t * y * z + s * x, t * z * z + c];
    const mul = (a, b) => [0, 1, 2].flatMap((i) => [0, 1, 2].map((j) => a[i * 3] * b[j] + a[i * 3 + 1] * b[3 + j] + a[i * 3 + 2] * b[6 + j]));
    rotation = mul(r, rotation);
    const d = [centre[0] - target[0], centre[1] - target[1], centre[2] - target[2]];
    centre = [0, 1, 2].map((i) => target[i] + r[i * 3] * d[0] + r[i * 3 + 1] * d[1] + r[i * 3 + 2] * d[2]);
  };
  canvas.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const dx = e.clientX - drag[0], dy = e.clientY - drag[1];
    drag = [e.clientX, e.clientY];
    rotateAbout([rotation[1], rotation[4], rotation[7]], -dx * 0.005);  // about the camera's down axis
    rotateAbout([rotation[0], rotation[3], rotation[6]], dy * 0.005);   // about its right axis
  });
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    const step = Math.sign(e.deltaY) * 0.1 * dist;
    for (let k = 0; k < 3; ++k) centre[k] -= step * rotation[k * 3 + 2];
  }, { passive: false });

  let depth = new Float32Array(count), indices = new Uint32Array(count), sortKey = '';
  const sort = (W, T) => {
    let lo = Infinity, hi = -Infinity;
    for (let i = 0; i < count; ++i) {
      const o = i * 11, dt = time - motion[o + 9];
      const p = [0, 1, 2].map((k) => motion[o + k] + motion[o + 3 + k] * dt + motion[o + 6 + k] * dt * dt);
      const z = W[6] * p[0] + W[7] * p[1] + W[8] * p[2] + T[2];
      depth[i] = z;
      if (z < lo) lo = z;
      if (z > hi) hi = z;
    }
    // Counting sort on 16-bit depth keys, far to near.
    const buckets = 65536, scaleKey = hi > lo ? (buckets - 1) / (hi - lo) : 0;
    const counts = new Uint32Array(buckets);
    const keys = new Uint16Array(count);
    for (let i = 0; i < count; ++i) counts[(keys[i] = buckets - 1 - Math.floor((depth[i] - lo) * scaleKey))]++;
    for (let i = 1; i < buckets; ++i) counts[i] += counts[i - 1];
    for (let i = count - 1; i >= 0; --i) indices[--counts[keys[i]]] = i;
    gl.bindBuffer(gl.ARRAY_BUFFER, order);
    gl.bufferData(gl.ARRAY_BUFFER, indices, gl.DYNAMIC_DRAW);
  };

  let last = performance.now(), frames = 0, resolveFirst;
  const firstFrame = new Promise((r) => { resolveFirst = r; });
  const frame = (now) => {
    const scale = fixed ? 1 : canvas.clientHeight / cam.height;
    const width = fixed ? cam.width : canvas.clientWidth, height = fixed ? cam.height : canvas.clientHeight;
    if (canvas.width !== width || canvas.height !== height) canvas.width = width, canvas.height = height;
    if (playing) time = (time + (now - last) / 4000) % 1;
    last = now;
    slider.value = Math.round(time * 1000);
    clock.textContent = time.toFixed(2);
    // World-to-camera: W = R^T, T = -R^T c.
    const W = [rotation[0], rotation[3], rotation[6], rotation[1], rotation[4], rotation[7], rotation[2], rotation[5], rotation[8]];
    const T = [0, 1, 2].map((i) => -(W[i * 3] * centre[0] + W[i * 3 + 1] * centre[1] + W[i * 3 + 2] * centre[2]));
    const key = `${time}|${W}|${T}`;
    if (key !== sortKey) sort(W, T), (sortKey = key);
    gl.viewport(0, 0, width, height);
    gl.clearColor(0, 0, 0, 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    // GLSL mat3 is column-major: pass W transposed so that u_rotation * v = W v.
    gl.uniformMatrix3fv(uniform('u_rotation'), false, [W[0], W[3], W[6], W[1], W[4], W[7], W[2], W[5], W[8]]);
    gl.uniform3fv(uniform('u_translation'), T);
    const cx = cam.cx ?? cam.width / 2, cy = cam.cy ?? cam.height / 2;
    gl.uniform4f(uniform('u_intrinsics'), cam.fx * scale, cam.fy * scale, fixed ? cx : width / 2, fixed ? cy : height / 2);
    gl.uniform2f(uniform('u_size'), width, height);
    gl.uniform1f(uniform('u_time'), time);
    gl.drawArraysInstanced(gl.TRIANGLE_FAN, 0, 4, count);
    if (++frames === 3) resolveFirst();
    requestAnimationFrame(frame);
  };
  requestAnimationFrame(frame);
  say(`${src}: ${count} Gaussians (${cameras.length} camera(s))`);
  await firstFrame;
  gl.finish();
  return { count, time };
}

window.atexView = {
  canvas,
  ready: main().catch((e) => {
    say(`error: ${e.message}`);
    throw e;
  }),
};
