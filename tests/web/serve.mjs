// A small static HTTP server on 127.0.0.1 for the sample viewer and the browser test.
//   /                -> samples/web            (the viewer pages)
//   /node_modules/   -> tests/web/node_modules (Babylon.js, meshoptimizer's decoder,
//                       PlayCanvas, three.js, Spark)
//   /players/        -> tests/web/players      (the PlayCanvas and three.js + Spark pages)
//   /data/           -> a folder of .glb / .splatv / .ply / .spz files (--data DIR)
// As a program:  node tests/web/serve.mjs --data out_dir [--port 8080]
// then open http://127.0.0.1:8080/?src=/data/scene.glb  or  /splatv.html?src=/data/scene.splatv
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
export const sourceDir = path.resolve(here, '..', '..');

const types = {
  '.html': 'text/html; charset=utf-8',
  '.js': 'text/javascript; charset=utf-8',
  '.mjs': 'text/javascript; charset=utf-8',
  '.cjs': 'text/javascript; charset=utf-8',
  '.json': 'application/json',
  '.png': 'image/png',
  '.glb': 'model/gltf-binary',
  '.gltf': 'model/gltf+json',
  '.bin': 'application/octet-stream',
  '.splatv': 'application/octet-stream',
  '.ply': 'application/octet-stream',
  '.spz': 'application/octet-stream',
  '.wasm': 'application/wasm',
  '.css': 'text/css',
};

// Starts serving; `data` is the folder behind /data/. Resolves to { url, close() }.
export function startServer({ data, port = 0, log = false } = {}) {
  const mounts = [
    ['/node_modules/', path.join(here, 'node_modules')],
    ['/players/', path.join(here, 'players')],
    ['/data/', data ? path.resolve(data) : null],
    ['/', path.join(sourceDir, 'samples', 'web')],
  ];
  const server = http.createServer((req, res) => {
    let pathname;
    try {
      pathname = decodeURIComponent(new URL(req.url, 'http://localhost').pathname);
    } catch {
      res.writeHead(400).end('bad URL');
      return;
    }
    if (pathname === '/') pathname = '/index.html';
    for (const [prefix, root] of mounts) {
      if (!pathname.startsWith(prefix) || !root) continue;
      const file = path.resolve(root, '.' + pathname.slice(prefix.length - 1));
      if (file !== root && !file.startsWith(root + path.sep)) break;  // outside the mount
      fs.stat(file, (err, st) => {
        if (err || !st.isFile()) {
          if (log) console.error(`404 ${pathname}`);
          res.writeHead(404).end('not found');
          return;
        }
        res.writeHead(200, {
          'Content-Type': types[path.extname(file).toLowerCase()] || 'application/octet-stream',
          'Content-Length': st.size,
          'Cache-Control': 'no-store',
        });
        fs.createReadStream(file).pipe(res);
      });
      return;
    }
    res.writeHead(404).end('not found');
  });
  return new Promise((resolve, reject) => {
    server.once('error', reject);
    server.listen(port, '127.0.0.1', () => {
      const { port: actual } = server.address();
      resolve({ url: `http://127.0.0.1:${actual}`, close: () => new Promise((r) => server.close(() => r())) });
    });
  });
}

if (process.argv[1] && path.resolve(process.argv[1]) === fileURLToPath(import.meta.url)) {
  const args = process.argv.slice(2);
  const get = (name, fallback) => {
    const i = args.indexOf(name);
    return i >= 0 && i + 1 < args.length ? args[i + 1] : fallback;
  };
  const { url } = await startServer({ data: get('--data', process.cwd()), port: Number(get('--port', 8080)), log: true });
  console.log(`serving samples/web at ${url}/  (files of --data under ${url}/data/)`);
  console.log(`  glTF in Babylon.js: ${url}/?src=/data/<file>.glb`);
  console.log(`  splaTV file:        ${url}/splatv.html?src=/data/<file>.splatv`);
  console.log(`  PlayCanvas:         ${url}/players/playcanvas.html?src=/data/<file>.glb|.ply&camera=/data/<camera>.json`);
  console.log(`  three.js + Spark:   ${url}/players/spark.html?src=/data/<file>.ply|.spz&camera=/data/<camera>.json`);
}
