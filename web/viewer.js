// The radbake viewer: a baked `.glb` in three.js with its lightmaps (and
// probes, when the bake has them). Open `index.html?url=<file.baked.glb>`
// or drop a `.glb` on the page. URL parameters (all optional):
//   url       the .glb to load
//   camera    a glTF camera's name (default: the first; else a framing)
//   view      lit | lightmap | albedo | probes   (default lit)
//   exposure  EV (default 0)
//   tonemap   aces | none (default aces, as `radbake preview`)
//   size      WxH of the canvas (default: the window)
//   loader    radbake (default) | hubs: the stock Hubs semantics, for tests
//   probes    the bake's probes.json (`radbake serve` adds it when the bake has probes)
//   manifest  the bake's manifest.json, for its light layers (default: the
//             one beside `url`, if there is one; none: no layers)
//   layer     NAME=W or NAME=R,G,B, repeatable: a light layer's weight, as
//             `radbake preview --layer` (layers not named keep 1), e.g.
//             ?url=…&layer=lamp=0&layer=ceiling=1,0.8,0.6
//   sun       x,y,z: a live bake's sun (towards it, y up), its bounce light
//             re-solved in the page (radbake-live.js), as `radbake relight
//             --sun-direction` / `radbake preview --sun-direction`
//   sun_irradiance  r,g,b W/m² (default: as baked)
//   sky       r,g,b: the sky's radiance (its layer × new / baked)
//   realtime  0: leave out the real-time lights (as `radbake preview
//             --no-realtime-lights`). By default the lit view draws, with
//             shadow maps, the lights whose direct light the lightmap does
//             not hold (mode live, indirect or realtime): a live sun turned
//             with its bounce light. The other views draw none.
// A bake with light layers gets an intensity slider (0–4) and a colour per
// layer (not the live layer, whose light is re-solved). A live bake gets
// the sun's controls: a time-of-day slider along its sun path, or, for a
// grid, azimuth (from +X towards +Z, as `radbake preview`) and elevation
// sliders, and the last update's time. `window.radbake` reports { ready,
// error, cameras, probes, layers, live, realtime } for scripts (layers: the names;
// realtime: the names of the real-time lights drawn;
// live: { light, sun, ms, iterations, residual } of the last update, null
// without a live bake); ready comes after the `layer`, `sun` and `sky`
// parameters are applied, and an unknown layer name, a malformed or
// zero-length sun, or a bad live.bin is an error naming it.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { HubsLightmapPlugin, RadbakeLightmapPlugin, loadRadbakeLayers, loadRadbakeLive, loadRadbakeProbes } from './radbake-three.js';

const params = new URLSearchParams(location.search);
const state = {
  view: params.get('view') || 'lit',
  exposure: Number(params.get('exposure') || 0),
  tonemap: params.get('tonemap') || 'aces',
};
window.radbake = { ready: false, error: null, cameras: [], probes: 0, layers: [], live: null, realtime: [] };

const canvas = document.getElementById('view');
const size = params.get('size') ? params.get('size').split('x').map(Number) : null;
const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.shadowMap.enabled = true;
renderer.shadowMap.type = THREE.PCFShadowMap;
const scene = new THREE.Scene();
const overlay = new THREE.Scene(); // probe spheres and probe-lit dynamic nodes
let camera = new THREE.PerspectiveCamera(50, 1, 0.05, 1000);
const controls = new OrbitControls(camera, canvas);
let gltfCameras = [];
let probes = null;
let layers = null;
let pendingWeights = null; // slider weights not applied yet: { name: [r, g, b] }
let live = null; // loadRadbakeLive's handle, for a live bake
let pendingSun = null; // a slider's sun direction not applied yet
const realtime = []; // the real-time lights drawn: { light, name, directional }
let sceneBounds = null; // the glTF scene's world box (the sun's shadow camera covers it)
const reshades = []; // re-shade probe-lit geometry after the probes change
const originals = new Map(); // mesh -> its lit (Lambert) material

function resize() {
  const [w, h] = size || [window.innerWidth, window.innerHeight - document.getElementById('bar').offsetHeight];
  renderer.setSize(w, h, false);
  canvas.style.width = `${w}px`;
  canvas.style.height = `${h}px`;
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}

/**
 * The lit material: Lambert, as radbake's convention (metallic ignored).
 * `userData.source` keeps `m`, whose emission light layers change.
 */
function lambert(m) {
  return new THREE.MeshLambertMaterial({
    userData: { source: m },
    name: m.name,
    color: m.color,
    map: m.map,
    emissive: m.emissive,
    emissiveMap: m.emissiveMap,
    emissiveIntensity: m.emissiveIntensity ?? 1,
    lightMap: m.lightMap,
    lightMapIntensity: m.lightMapIntensity ?? 1,
    alphaTest: m.alphaTest,
    transparent: m.transparent,
    depthWrite: m.depthWrite,
    opacity: m.opacity,
    side: m.side,
    vertexColors: m.vertexColors,
  });
}

/** The material of `view` for a lit material. */
function forView(lit) {
  if (state.view === 'lightmap') {
    return new THREE.MeshLambertMaterial({ color: 0xffffff, lightMap: lit.lightMap, lightMapIntensity: lit.lightMapIntensity, side: lit.side });
  }
  if (state.view === 'albedo') {
    return new THREE.MeshBasicMaterial({ color: lit.color, map: lit.map, alphaTest: lit.alphaTest, side: lit.side, vertexColors: lit.vertexColors });
  }
  return lit;
}

function applyView() {
  for (const [mesh, lit] of originals) mesh.material = forView(lit);
  renderer.toneMapping = state.tonemap === 'none' ? THREE.NoToneMapping : THREE.ACESFilmicToneMapping;
  renderer.toneMappingExposure = 2 ** state.exposure;
  for (const { light } of realtime) light.visible = state.view === 'lit' && params.get('realtime') !== '0';
  overlay.visible = state.view === 'probes' || overlay.userData.dynamic;
  for (const s of overlay.userData.spheres || []) s.visible = state.view === 'probes';
}

/**
 * Vertex colours E/π(n) from an SH, per vertex (three.js's own SH
 * evaluation), into the geometry's colour attribute (made on first use).
 */
function shadeFromProbes(geometry, matrixWorld, shAt) {
  const pos = geometry.attributes.position;
  const nrm = geometry.attributes.normal;
  if (!geometry.attributes.color) geometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(pos.count * 3), 3));
  const colors = geometry.attributes.color.array;
  const p = new THREE.Vector3();
  const n = new THREE.Vector3();
  const e = new THREE.Vector3();
  const normalMatrix = new THREE.Matrix3().getNormalMatrix(matrixWorld);
  for (let i = 0; i < pos.count; i++) {
    p.fromBufferAttribute(pos, i).applyMatrix4(matrixWorld);
    n.fromBufferAttribute(nrm, i).applyMatrix3(normalMatrix).normalize();
    shAt(p).getIrradianceAt(n, e).multiplyScalar(1 / Math.PI);
    colors.set([Math.max(e.x, 0), Math.max(e.y, 0), Math.max(e.z, 0)], 3 * i);
  }
  geometry.attributes.color.needsUpdate = true;
}

/** Shades probe-lit geometry with `shade()` now and whenever the probes change. */
function probeLit(shade) {
  shade();
  reshades.push(shade);
}

function addProbeSpheres() {
  const spheres = [];
  const v = probes.meta.volumes[0];
  const spacing = Math.min(...v.spacing);
  for (let i = 0; i < probes.count; i++) {
    const g = new THREE.SphereGeometry(0.15 * spacing, 12, 8);
    const invalid = probes.meta.invalid_probes.includes(i);
    let mat;
    if (invalid) {
      mat = new THREE.MeshBasicMaterial({ color: 0xff0000 });
    } else {
      probeLit(() => {
        const sh = probes.probe(i).sh;
        shadeFromProbes(g, new THREE.Matrix4(), () => sh);
      });
      mat = new THREE.MeshBasicMaterial({ vertexColors: true });
    }
    const s = new THREE.Mesh(g, mat);
    s.position.copy(probes.position(i));
    overlay.add(s);
    spheres.push(s);
  }
  overlay.userData.spheres = spheres;
}

/** Nodes marked `extras.radbake.dynamic` are lit from the probes. */
function lightDynamicNodes(root) {
  root.traverse((o) => {
    if (!o.isMesh) return;
    let dyn = false;
    for (let a = o; a; a = a.parent) if (a.userData?.radbake?.dynamic) dyn = true;
    if (!dyn || !probes) return;
    o.updateWorldMatrix(true, false);
    const g = o.geometry.clone();
    probeLit(() => shadeFromProbes(g, o.matrixWorld, probes.shAt));
    const lit = originals.get(o);
    const m = new THREE.MeshBasicMaterial({ color: lit.color, map: lit.map, vertexColors: true, side: lit.side });
    o.geometry = g;
    originals.set(o, m);
    overlay.userData.dynamic = true;
  });
}

function useCamera(name) {
  const c = gltfCameras.find((c) => c.name === name) || gltfCameras[0];
  if (!c) return;
  c.updateWorldMatrix(true, false);
  camera.fov = c.fov;
  camera.near = c.near;
  camera.far = c.far;
  // The node may scale (the breakfast room's cameras do): decompose.
  c.matrixWorld.decompose(camera.position, camera.quaternion, new THREE.Vector3());
  const forward = new THREE.Vector3(0, 0, -1).applyQuaternion(camera.quaternion);
  controls.target.copy(camera.position).addScaledVector(forward, 1);
  camera.updateProjectionMatrix();
}

function frame(root) {
  const box = new THREE.Box3().setFromObject(root);
  const c = box.getCenter(new THREE.Vector3());
  const r = box.getSize(new THREE.Vector3()).length() / 2;
  camera.position.copy(c).add(new THREE.Vector3(0, r * 0.3, r * 1.8));
  camera.near = r / 1000;
  camera.far = r * 10;
  controls.target.copy(c);
  camera.updateProjectionMatrix();
}

/**
 * The bake's manifest.json for `url`: the `manifest` parameter, else the
 * one beside `url` if the server has it; null for `manifest=none` and a
 * dropped file.
 */
async function manifestFor(url) {
  const given = params.get('manifest');
  if (given) return given === 'none' ? null : given;
  if (url.startsWith('blob:')) return null;
  const beside = new URL('manifest.json', new URL(url, location.href)).href;
  const response = await fetch(beside);
  return response.ok && (await response.json()) ? beside : null;
}

/** The `layer` parameters as { name: w or [r, g, b] }; a malformed one is an error naming it. */
function layerParams() {
  const weights = {};
  for (const entry of params.getAll('layer')) {
    const m = /^([A-Za-z_][A-Za-z0-9_]*)=([^=]+)$/.exec(entry);
    const values = m ? m[2].split(',').map((v) => (/^\s*[-+0-9.eE]+\s*$/.test(v) ? Number(v) : NaN)) : [];
    if (!m || ![1, 3].includes(values.length) || values.some((v) => !Number.isFinite(v))) {
      throw new Error(`layer=${entry}: expected NAME=W or NAME=R,G,B`);
    }
    weights[m[1]] = values.length === 1 ? values[0] : values;
  }
  return weights;
}

/** The sliders: per layer an intensity (0–4) and a colour, their product the weight. */
function layerControls() {
  const bar = document.getElementById('layers');
  const fixed = live ? live.runtime.header.layer : null; // re-solved, not weighted
  bar.replaceChildren(
    ...layers.names.filter((name) => name !== fixed).map((name) => {
      const rgb = layers.weight(name);
      const intensity = Math.max(...rgb);
      const colour = intensity > 0 ? new THREE.Color(...rgb.map((c) => c / intensity)) : new THREE.Color(1, 1, 1);
      const label = document.createElement('label');
      const slider = Object.assign(document.createElement('input'), { type: 'range', min: 0, max: 4, step: 0.05, value: intensity, title: `${name} intensity` });
      const picker = Object.assign(document.createElement('input'), { type: 'color', value: `#${colour.getHexString()}`, title: `${name} colour` });
      const update = () => {
        const c = new THREE.Color(picker.value); // sRGB hex to linear
        pendingWeights = { ...pendingWeights, [name]: [c.r, c.g, c.b].map((v) => v * Number(slider.value)) };
      };
      slider.addEventListener('input', update);
      picker.addEventListener('input', update);
      label.append(`${name} `, slider, picker);
      return label;
    }),
  );
  resize();
}

/** URL parameter `name` as three numbers, or null if absent; a malformed one is an error naming it. */
function vec3Param(name) {
  const given = params.get(name);
  if (given === null) return null;
  const v = given.split(',').map((x) => (/^\s*[-+0-9.eE]+\s*$/.test(x) ? Number(x) : NaN));
  if (v.length !== 3 || v.some((x) => !Number.isFinite(x))) throw new Error(`${name}=${given}: expected three comma-separated numbers`);
  return v;
}

/** Degrees of elevation and azimuth (from +X towards +Z, as `radbake preview`) of a direction. */
function angles([x, y, z]) {
  const len = Math.hypot(x, y, z);
  return [(Math.asin(Math.min(Math.max(y / len, -1), 1)) * 180) / Math.PI, (Math.atan2(z, x) * 180) / Math.PI];
}

/**
 * A real-time light for glTF light `l` (GLTFLoader's, taken out of the
 * scene): a directional light is made again in the scene, its shadow
 * camera an orthographic box around the scene's bounds; a point or spot
 * light goes back where it was. Intensities as the glTF's (W/m² and W/sr
 * as three.js's lux and candela: three's Lambert gives albedo × E cos θ
 * / π, the lightmap's albedo × value). Returns { light, name, directional }.
 */
function realtimeLight(l) {
  const name = l.name;
  if (!l.isDirectionalLight) {
    l.castShadow = true;
    scene.attach(l); // its world transform kept
    return { light: l, name, directional: false };
  }
  const towards = new THREE.Vector3(0, 0, 1).applyQuaternion(l.getWorldQuaternion(new THREE.Quaternion()));
  l.removeFromParent();
  const light = new THREE.DirectionalLight(l.color.clone(), l.intensity);
  light.name = name;
  light.castShadow = true;
  light.shadow.mapSize.set(4096, 4096);
  scene.add(light, light.target);
  const entry = { light, name, directional: true };
  aimSun(entry, towards.toArray());
  return entry;
}

/** Points directional light `entry` towards-the-sun `direction`, its shadow box around the scene. */
function aimSun({ light }, direction) {
  const d = new THREE.Vector3(...direction).normalize();
  const centre = sceneBounds.getCenter(new THREE.Vector3());
  const r = Math.max(sceneBounds.getSize(new THREE.Vector3()).length() / 2, 1e-3);
  light.position.copy(centre).addScaledVector(d, 2 * r);
  light.target.position.copy(centre);
  const cam = light.shadow.camera;
  Object.assign(cam, { left: -r, right: r, top: r, bottom: -r, near: 0.5 * r, far: 3.5 * r });
  cam.updateProjectionMatrix();
  light.shadow.bias = -0.0005;
  light.shadow.normalBias = (2 * r) / light.shadow.mapSize.x;
  light.updateMatrixWorld(true);
  light.target.updateMatrixWorld(true);
}

/** The live light drawn in real time follows the last update: direction, colour and irradiance. */
function followLiveSun() {
  const suns = realtime.filter((r) => r.directional && r.mode === 'live');
  const entry = suns.find((r) => r.name === live.light) || (suns.length === 1 ? suns[0] : null);
  if (!entry) return;
  const { direction, irradiance } = live.sun();
  aimSun(entry, direction);
  const e = Math.max(...irradiance);
  entry.light.intensity = e;
  if (e > 0) entry.light.color.setRGB(irradiance[0] / e, irradiance[1] / e, irradiance[2] / e, THREE.LinearSRGBColorSpace);
}

/** `window.radbake.live` and the update time shown, from the last update. */
function reportLive() {
  const { cost } = live;
  followLiveSun();
  const [elevation, azimuth] = angles(live.sun().direction);
  window.radbake.live = { light: live.light, sun: live.sun().direction, ms: cost.ms, iterations: cost.iterations, residual: cost.residual, solve: cost.solve, pages: cost.pages, lightmap: cost.lightmap };
  document.getElementById('live-cost').textContent =
    `${live.light}: elevation ${elevation.toFixed(1)}°, azimuth ${azimuth.toFixed(1)}°; update ${cost.ms.toFixed(1)} ms ` +
    `(solve ${cost.solve.toFixed(1)}, pages ${cost.pages.toFixed(1)}, lightmap ${cost.lightmap.toFixed(1)}), ${cost.iterations} iterations`;
}

/**
 * The sun's sliders: along the live light's sun path (its samples
 * 0 … n − 1, between them interpolated and normalised), or azimuth and
 * elevation for a grid bake.
 */
async function liveControls() {
  const { nearestOnPath } = await import('./radbake-live.js');
  const path = live.lights[0].path;
  const bar = document.getElementById('live');
  const slider = (title, min, max, step, value) => Object.assign(document.createElement('input'), { type: 'range', min, max, step, value, title });
  const label = (text, ...inputs) => {
    const l = document.createElement('label');
    l.append(text, ...inputs);
    return l;
  };
  const sun = live.sun().direction;
  const cost = Object.assign(document.createElement('span'), { id: 'live-cost' });
  if (path) {
    const at = nearestOnPath(path, sun) || { k: 0, t: 0 };
    const time = slider('time of day: along the sun path', 0, path.length - 1, 0.01, at.k + at.t);
    time.addEventListener('input', () => {
      const s = Number(time.value);
      const k = Math.min(Math.floor(s), path.length - 2);
      const t = path.length > 1 ? s - k : 0;
      const a = path[Math.max(k, 0)];
      const b = path[Math.min(k + 1, path.length - 1)];
      pendingSun = [0, 1, 2].map((c) => (1 - t) * a[c] + t * b[c]);
    });
    bar.replaceChildren(label('time of day ', time), cost);
  } else {
    const [e, a] = angles(sun);
    const elevation = slider('sun elevation (degrees)', 0, 90, 0.5, Math.max(e, 0));
    const azimuth = slider('sun azimuth (degrees, from +X towards +Z)', -180, 180, 0.5, a);
    const turn = () => {
      const el = (Number(elevation.value) * Math.PI) / 180;
      const az = (Number(azimuth.value) * Math.PI) / 180;
      pendingSun = [Math.cos(el) * Math.cos(az), Math.sin(el), Math.cos(el) * Math.sin(az)];
    };
    elevation.addEventListener('input', turn);
    azimuth.addEventListener('input', turn);
    bar.replaceChildren(label('sun elevation ', elevation), label('azimuth ', azimuth), cost);
  }
  reportLive();
  resize();
}

async function load(url) {
  const Plugin = params.get('loader') === 'hubs' ? HubsLightmapPlugin : RadbakeLightmapPlugin;
  const loader = new GLTFLoader().register((parser) => new Plugin(parser));
  const gltf = await loader.loadAsync(url);
  scene.clear();
  overlay.clear();
  originals.clear();
  // The glTF's punctual lights: the baked ones are in the lightmaps already
  // (three's GLTFLoader would add them as real-time lights and count them
  // twice); those whose direct light the lightmap leaves out are drawn.
  const lights = [];
  gltf.scene.traverse((o) => o.isLight && lights.push(o));
  scene.add(gltf.scene);
  scene.updateMatrixWorld(true);
  sceneBounds = new THREE.Box3().setFromObject(gltf.scene);
  realtime.length = 0;
  for (const l of lights) {
    const mode = l.userData && l.userData.radbake && l.userData.radbake.mode;
    if (['live', 'indirect', 'realtime'].includes(mode)) realtime.push({ ...realtimeLight(l), mode });
    else l.removeFromParent();
  }
  window.radbake.realtime = realtime.map((r) => r.name);
  reshades.length = 0;
  probes = params.get('probes') ? await loadRadbakeProbes(params.get('probes')) : null;
  window.radbake.probes = probes ? probes.count : 0;
  const weights = layerParams();
  const sun = vec3Param('sun');
  const sunIrradiance = vec3Param('sun_irradiance');
  const sky = vec3Param('sky');
  const manifest = await manifestFor(url);
  if (!manifest && Object.keys(weights).length) {
    throw new Error(`layer=${params.getAll('layer')[0]}: no manifest.json beside ${url} (name one with manifest=)`);
  }
  layers = manifest ? await loadRadbakeLayers(manifest, gltf.scene, probes) : null;
  // A live bake: its sun solved in the page, the live layer's pages replaced.
  const baked = manifest ? (await (await fetch(manifest)).json()).live : null;
  const liveParam = ['sun', 'sun_irradiance', 'sky'].find((p) => params.has(p));
  if (!baked && liveParam) {
    throw new Error(`${liveParam}=${params.get(liveParam)}: ${manifest ? `${manifest} lists no live light (bake with --live)` : `no manifest.json beside ${url}`}`);
  }
  live = null;
  window.radbake.live = null;
  if (baked) {
    const given = sun || sunIrradiance ? { direction: sun || baked.lights[0].direction, irradiance: sunIrradiance } : null;
    live = await loadRadbakeLive(manifest, layers, { sun: given, sky });
  }
  if (layers) layers.setLayerWeights(weights);
  window.radbake.layers = layers ? layers.names : [];
  gltf.scene.traverse((o) => {
    if (o.isMesh) {
      const lit = lambert(o.material);
      originals.set(o, lit);
      o.castShadow = true;
      o.receiveShadow = true;
    }
  });
  gltfCameras = gltf.cameras;
  window.radbake.cameras = gltfCameras.map((c) => c.name);
  if (layers && layers.names.length) layerControls();
  if (live) await liveControls();
  if (probes) {
    addProbeSpheres();
    lightDynamicNodes(gltf.scene);
    // Dynamic nodes draw in the overlay pass, lit from the probes only.
    for (const [mesh, m] of originals) if (m.isMeshBasicMaterial && m.vertexColors) overlay.attach(mesh);
  }
  const select = document.getElementById('camera');
  select.replaceChildren(...['(orbit)', ...window.radbake.cameras].map((n) => new Option(n, n)));
  if (gltfCameras.length) {
    const name = params.get('camera') || gltfCameras[0].name;
    useCamera(name);
    select.value = name;
  } else {
    frame(gltf.scene);
  }
  controls.update();
  applyView();
}

function render() {
  renderer.autoClear = true;
  renderer.render(scene, camera);
  if (overlay.visible) {
    renderer.autoClear = false;
    renderer.render(overlay, camera);
  }
}

function ui() {
  const bind = (id, key, parse = (v) => v) => {
    const el = document.getElementById(id);
    el.value = state[key];
    el.addEventListener('input', () => {
      state[key] = parse(el.value);
      applyView();
    });
  };
  bind('viewmode', 'view');
  bind('exposure', 'exposure', Number);
  bind('tonemap', 'tonemap');
  document.getElementById('camera').addEventListener('change', (e) => {
    if (e.target.value !== '(orbit)') useCamera(e.target.value);
  });
  window.addEventListener('resize', resize);
  document.body.addEventListener('dragover', (e) => e.preventDefault());
  document.body.addEventListener('drop', async (e) => {
    e.preventDefault();
    const file = e.dataTransfer.files[0];
    if (file) await load(URL.createObjectURL(file));
  });
}

ui();
resize();
const url = params.get('url');
(url ? load(url) : Promise.resolve())
  .then(() => {
    render();
    window.radbake.ready = true;
    renderer.setAnimationLoop(() => {
      if (pendingWeights) {
        layers.setLayerWeights(pendingWeights);
        pendingWeights = null;
        for (const shade of reshades) shade();
        for (const lit of originals.values()) if (lit.userData.source) lit.emissive.copy(lit.userData.source.emissive);
      }
      if (pendingSun) {
        live.setSun(pendingSun);
        pendingSun = null;
        reportLive();
      }
      controls.update();
      render();
    });
  })
  .catch((e) => {
    window.radbake.error = String(e);
    document.getElementById('status').textContent = `error: ${e}`;
  });
