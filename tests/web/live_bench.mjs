// Times the three.js live runtime in headless Chromium on a live bake, as
// live/examples/bench.rs times the Rust one: the sun stepped along its
// path (or across the grid's middle row) one sample (≈ 0.7° on a
// 256-sample path) per update, each halfway between two samples,
// warm-started from the last. Two runs:
//
// 1. the run time alone (web/radbake-live.js: `RadbakeLive.update`, the
//    direct light, the solve, the texels and the live layer's pages),
//    and `probeDelta` (the probes' change) after it;
// 2. as a page uses it (web/radbake-three.js: the `.glb`, its probes and
//    light layers, `loadRadbakeLive`'s `setSun`): the update, the probes'
//    change, and the lightmap pages and probes recombined;
// 3. the same with the lightmap alone (the probes not given).
//
// Prints the load times, the median and worst update and its parts, and
// the iterations. A benchmark, not a test:
//
//     node live_bench.mjs <bake dir> [steps]
//
// Serves web/ and the bake folder itself on a free port (no `radbake
// serve` needed).

import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { launchChromium } from './chromium.mjs';

const [dirArg, stepsArg] = process.argv.slice(2);
if (!dirArg) {
  console.error('usage: node live_bench.mjs <bake dir> [steps]');
  process.exit(2);
}
const dir = fs.statSync(dirArg).isDirectory() ? dirArg : path.dirname(dirArg);
const steps = Number(stepsArg || 60);
const web = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../../web');
// A page with three.js's import map and nothing else (no renderer).
const page = `<!doctype html><title>live bench</title><link rel="icon" href="data:,"><script type="importmap">
{ "imports": { "three": "/vendor/three/build/three.module.js", "three/addons/": "/vendor/three/examples/jsm/" } }
</script>`;
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(req.url.split('?')[0]);
  const file = url.startsWith('/bake/') ? path.join(dir, path.basename(url)) : path.join(web, path.normalize(url));
  if (url === '/') {
    res.writeHead(200, { 'Content-Type': 'text/html' });
    res.end(page);
  } else if (file.startsWith(web) || url.startsWith('/bake/')) {
    fs.readFile(file, (e, body) => {
      res.writeHead(e ? 404 : 200, { 'Content-Type': file.endsWith('.js') ? 'text/javascript' : 'application/octet-stream' });
      res.end(e ? undefined : body);
    });
  } else {
    res.writeHead(404);
    res.end();
  }
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const origin = `http://127.0.0.1:${server.address().port}`;

const browser = await launchChromium({ gl: false });

/** Median and worst of `key` over `runs`. */
function stat(runs, key) {
  const v = runs.map((r) => r[key]).sort((a, b) => a - b);
  return `${v[v.length >> 1].toFixed(1)} / ${v[v.length - 1].toFixed(1)}`;
}

/** "a–b iterations, median m" over `runs`. */
function iterations(runs) {
  const v = runs.map((r) => r.iterations).sort((a, b) => a - b);
  return `${v[0]}–${v[v.length - 1]} iterations, median ${v[v.length >> 1]}`;
}

try {
  const tab = await browser.newPage();
  tab.on('pageerror', (e) => console.error(String(e)));
  tab.on('console', (m) => m.type() === 'error' && console.error(m.text()));
  await tab.goto(`${origin}/`);
  const result = await tab.evaluate(async (steps) => {
    const manifest = await (await fetch('/bake/manifest.json')).json();
    if (!manifest.live) throw new Error('the bake has no live lights (no `live` in its manifest.json)');
    const { parseRadbakeLive, RadbakeLive, nodeDirection } = await import('/radbake-live.js');
    const bytes = await (await fetch(`/bake/${manifest.live.file}`)).arrayBuffer();
    const t0 = performance.now();
    const data = parseRadbakeLive(bytes, manifest.live.file);
    const t1 = performance.now();
    const runtime = new RadbakeLive(data);
    const t2 = performance.now();
    const h = data.header;
    const light = h.lights[0];
    const dirs = light.path || Array.from({ length: h.grid }, (_, i) => nodeDirection(h.grid, i, h.grid >> 1));
    // Halfway between samples: never a table direction.
    const mid = (k) => {
      const i = k % (dirs.length - 1);
      return [0, 1, 2].map((c) => 0.5 * (dirs[i][c] + dirs[i + 1][c]));
    };
    const start = dirs.length >> 2;
    const first = runtime.update({ direction: mid(start) });
    const alone = [];
    for (let s = 0; s < steps; s++) {
      const u = runtime.update({ direction: mid(start + s + 1) });
      const t = performance.now();
      const delta = runtime.probeDelta();
      alone.push({ ...u, probesMs: delta ? performance.now() - t : NaN });
    }

    // As a page uses it: the glb, its layers, loadRadbakeLive.
    const { GLTFLoader } = await import('three/addons/loaders/GLTFLoader.js');
    const R = await import('/radbake-three.js');
    const gltf = await new GLTFLoader().register((p) => new R.RadbakeLightmapPlugin(p)).loadAsync(`/bake/${manifest.baked_gltf}`);
    const t3 = performance.now();
    const probes = manifest.probes ? await R.loadRadbakeProbes('/bake/probes.json') : null;
    const layers = await R.loadRadbakeLayers('/bake/manifest.json', gltf.scene, probes);
    const t4 = performance.now();
    const live = await R.loadRadbakeLive('/bake/manifest.json', layers, { sun: { direction: mid(start) } });
    const t5 = performance.now();
    const paged = [];
    for (let s = 0; s < steps; s++) paged.push(live.setSun(mid(start + s + 1)));
    // The lightmap alone: the same, the probes not given.
    const plain = await new GLTFLoader().register((p) => new R.RadbakeLightmapPlugin(p)).loadAsync(`/bake/${manifest.baked_gltf}`);
    const pageOnly = await R.loadRadbakeLive('/bake/manifest.json', await R.loadRadbakeLayers('/bake/manifest.json', plain.scene), { sun: { direction: mid(start) } });
    const lightmap = [];
    for (let s = 0; s < steps; s++) lightmap.push(pageOnly.setSun(mid(start + s + 1)));
    return {
      patches: h.patches,
      entries: h.entries,
      texels: h.texels,
      pixels: h.pages.reduce((a, p) => a + p.width * p.height, 0),
      directions: dirs.length,
      parse: t1 - t0,
      setup: t2 - t1,
      layersLoad: t4 - t3,
      liveLoad: t5 - t4,
      first,
      alone,
      paged,
      lightmap,
    };
  }, steps);
  const r = result;
  console.log(
    `${await browser.version()}, one thread: ${r.patches} patches, ${r.entries} entries of F, ${r.texels} texels, ${r.pixels} page pixels, ${r.directions} directions`,
  );
  console.log(
    `run time alone: parse and check ${r.parse.toFixed(0)} ms, set-up ${r.setup.toFixed(0)} ms, first update (from zero) ${r.first.ms.toFixed(0)} ms, ${r.first.iterations} iterations`,
  );
  console.log(
    `  ${steps} updates, sun stepped one sample each (median / worst): solve ${stat(r.alone, 'solveMs')} ms (${iterations(r.alone)}), ` +
      `texels + pages ${stat(r.alone, 'pagesMs')} ms; update ${stat(r.alone, 'ms')} ms; the probes' change ${stat(r.alone, 'probesMs')} ms`,
  );
  console.log(`three.js: layers loaded in ${r.layersLoad.toFixed(0)} ms, loadRadbakeLive ${r.liveLoad.toFixed(0)} ms`);
  console.log(
    `  ${steps} setSun (median / worst): update ${stat(r.paged, 'solve')} + ${stat(r.paged, 'pages')} ms (solve, pages), ` +
      `probes' change ${stat(r.paged, 'probes')} ms, lightmap and probes recombined ${stat(r.paged, 'lightmap')} ms; in all ${stat(r.paged, 'ms')} ms (${iterations(r.paged)})`,
  );
  console.log(
    `  the lightmap alone (no probes given), ${steps} setSun: update ${stat(r.lightmap, 'solve')} + ${stat(r.lightmap, 'pages')} ms, ` +
      `recombined ${stat(r.lightmap, 'lightmap')} ms; in all ${stat(r.lightmap, 'ms')} ms`,
  );
} finally {
  await browser.close();
  server.close();
}
