// Runs the three.js live runtime on a live bake served by `radbake
// serve`, in headless Chromium, as an engine would: the `.glb` through
// RadbakeLightmapPlugin, its light layers (loadRadbakeLayers), the live
// solve at the baked sun (loadRadbakeLive), then the sky and the sun set
// (setSky, setSun: warm-started from the baked sun's solution). Writes
// lightmap page 0 as combined (every layer, before the half-float
// conversion) as raw little-endian f32 RGB, rows from v = 0, and the
// probes as recombined (the live layer's moved by the runtime's
// probeDelta) as `probes.bin` lays them out, to <out.f32>.probes:
//
//     node live_check.mjs <origin> <sun x,y,z> <sky r,g,b | -> <out.f32>
//
// Prints JSON: { width, height, light, iterations, residual, ms, errors }.

import fs from 'node:fs';
import { launchChromium } from './chromium.mjs';

const [origin, sunArg, skyArg, out] = process.argv.slice(2);
if (!origin || !sunArg || !skyArg || !out) {
  console.error('usage: node live_check.mjs <origin> <sun x,y,z> <sky r,g,b | -> <out.f32>');
  process.exit(2);
}
const sun = sunArg.split(',').map(Number);
const sky = skyArg === '-' ? null : skyArg.split(',').map(Number);
const browser = await launchChromium();
const errors = [];
try {
  const tab = await browser.newPage();
  tab.on('pageerror', (e) => errors.push(String(e)));
  tab.on('console', (m) => {
    if (m.type() === 'error') errors.push(m.text());
  });
  // The viewer page with no model: its import map resolves `three`.
  await tab.goto(`${origin}/`, { waitUntil: 'domcontentloaded', timeout: 120000 });
  await tab.waitForFunction('window.radbake && (window.radbake.ready || window.radbake.error)', { timeout: 120000 });
  const result = await tab.evaluate(
    async (sun, sky) => {
      const { GLTFLoader } = await import('three/addons/loaders/GLTFLoader.js');
      const R = await import('/radbake-three.js');
      const manifest = await (await fetch('/bake/manifest.json')).json();
      const loader = new GLTFLoader().register((parser) => new R.RadbakeLightmapPlugin(parser));
      const gltf = await loader.loadAsync(`/bake/${manifest.baked_gltf}`);
      const probes = await R.loadRadbakeProbes('/bake/probes.json');
      const layers = await R.loadRadbakeLayers('/bake/manifest.json', gltf.scene, probes);
      const live = await R.loadRadbakeLive('/bake/manifest.json', layers);
      if (sky) live.setSky(sky);
      const cost = live.setSun(sun);
      const { width, height, rgb } = layers.page(0);
      const bytes = new Uint8Array(rgb.buffer, rgb.byteOffset, rgb.byteLength);
      const base64 = (bytes) => {
        let binary = '';
        for (let i = 0; i < bytes.length; i += 0x8000) binary += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
        return btoa(binary);
      };
      const p = probes.floats;
      return { width, height, light: live.light, ...cost, data: base64(bytes), probeData: base64(new Uint8Array(p.buffer, p.byteOffset, p.byteLength)) };
    },
    sun,
    sky,
  );
  fs.writeFileSync(out, Buffer.from(result.data, 'base64'));
  fs.writeFileSync(`${out}.probes`, Buffer.from(result.probeData, 'base64'));
  delete result.data;
  delete result.probeData;
  console.log(JSON.stringify({ ...result, errors }));
} catch (e) {
  console.log(JSON.stringify({ errors: [...errors, String(e)] }));
} finally {
  await browser.close();
}
