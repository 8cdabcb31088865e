// A radbake probe as a three.js user loads it: headless Chromium (the
// system's, driven by puppeteer-core) renders a white Lambert sphere lit
// only by `new THREE.LightProbe(sh)`, with `sh` built from probes.json /
// probes.bin, into a float render target, and prints the linear radiance
// at sample pixels with the sphere's normal there, as JSON on stdout:
//
//     node probe_check.mjs <bake dir> <probe index>
//
// The caller (tests/web.rs) compares each value with radbake's own
// irradiance / π for that normal. Set CHROMIUM to the browser's path
// (default: chromium on PATH).

import http from 'node:http';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { launchChromium } from './chromium.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const [dir, indexArg] = process.argv.slice(2);
if (!dir || indexArg === undefined) {
  console.error('usage: node probe_check.mjs <bake dir> <probe index>');
  process.exit(2);
}
const index = Number(indexArg);

// The probe's 9 RGB coefficients, as a three.js user would read them.
const meta = JSON.parse(fs.readFileSync(path.join(dir, 'probes.json'), 'utf8'));
const bin = fs.readFileSync(path.join(dir, meta.binary));
const floats = new Float32Array(bin.buffer, bin.byteOffset, bin.byteLength / 4);
if (!(index >= 0 && index < meta.probes)) {
  console.error(`probe ${index} out of range (${meta.probes} probes)`);
  process.exit(2);
}
const coefficients = Array.from(floats.slice(index * 27, index * 27 + 27));

const SIZE = 128;
const page = `<!doctype html><html><body><canvas id="c" width="${SIZE}" height="${SIZE}"></canvas>
<script type="module">
import * as THREE from '/three.module.js';
const c = ${JSON.stringify(coefficients)};
const renderer = new THREE.WebGLRenderer({ canvas: document.getElementById('c'), antialias: false });
renderer.toneMapping = THREE.NoToneMapping;
renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
const scene = new THREE.Scene();
const sh = new THREE.SphericalHarmonics3();
for (let k = 0; k < 9; k++) sh.coefficients[k].set(c[3 * k], c[3 * k + 1], c[3 * k + 2]);
scene.add(new THREE.LightProbe(sh, 1));
const sphere = new THREE.Mesh(new THREE.SphereGeometry(1, 256, 128), new THREE.MeshLambertMaterial({ color: 0xffffff }));
scene.add(sphere);
const camera = new THREE.OrthographicCamera(-1.1, 1.1, 1.1, -1.1, 0.1, 10);
camera.position.set(0, 0, 5);
camera.lookAt(0, 0, 0);
const target = new THREE.WebGLRenderTarget(${SIZE}, ${SIZE}, { type: THREE.FloatType });
renderer.setRenderTarget(target);
renderer.render(scene, camera);
const buf = new Float32Array(${SIZE} * ${SIZE} * 4);
renderer.readRenderTargetPixels(target, 0, 0, ${SIZE}, ${SIZE}, buf);
window.result = { pixels: Array.from(buf), three: THREE.REVISION };
</script></body></html>`;

const threeFile = path.join(here, 'node_modules', 'three', 'build', 'three.module.js');
const threeCore = path.join(here, 'node_modules', 'three', 'build', 'three.core.js');
const server = http.createServer((req, res) => {
  const files = { '/three.module.js': threeFile, '/three.core.js': threeCore };
  if (files[req.url]) {
    res.writeHead(200, { 'content-type': 'text/javascript' });
    res.end(fs.readFileSync(files[req.url]));
  } else {
    res.writeHead(200, { 'content-type': 'text/html' });
    res.end(page);
  }
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const url = `http://127.0.0.1:${server.address().port}/`;

const browser = await launchChromium();
try {
  const tab = await browser.newPage();
  const errors = [];
  tab.on('pageerror', (e) => errors.push(String(e)));
  tab.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  await tab.goto(url, { waitUntil: 'domcontentloaded', timeout: 120000 });
  await tab.waitForFunction('window.result !== undefined || false', { timeout: 120000 }).catch(() => {});
  const result = await tab.evaluate(() => window.result);
  if (!result) throw new Error(`the page did not render: ${errors.join('; ')}`);
  // Pixel (x, y) from the bottom left; the sphere's normal where it is well
  // inside the silhouette.
  const samples = [];
  for (let y = 4; y < SIZE; y += 8) {
    for (let x = 4; x < SIZE; x += 8) {
      const u = ((x + 0.5) / SIZE) * 2.2 - 1.1;
      const v = ((y + 0.5) / SIZE) * 2.2 - 1.1;
      const r2 = u * u + v * v;
      if (r2 > 0.8) continue;
      const i = 4 * (y * SIZE + x);
      samples.push({ normal: [u, v, Math.sqrt(1 - r2)], rgb: result.pixels.slice(i, i + 3) });
    }
  }
  console.log(JSON.stringify({ three: result.three, probe: index, samples }));
} finally {
  await browser.close();
  server.close();
}
