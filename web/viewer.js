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
// `window.radbake` reports { ready, error, cameras, probes } for scripts.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { HubsLightmapPlugin, RadbakeLightmapPlugin, loadRadbakeProbes } from './radbake-three.js';

const params = new URLSearchParams(location.search);
const state = {
  view: params.get('view') || 'lit',
  exposure: Number(params.get('exposure') || 0),
  tonemap: params.get('tonemap') || 'aces',
};
window.radbake = { ready: false, error: null, cameras: [], probes: 0 };

const canvas = document.getElementById('view');
const size = params.get('size') ? params.get('size').split('x').map(Number) : null;
const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
const scene = new THREE.Scene();
const overlay = new THREE.Scene(); // probe spheres and probe-lit dynamic nodes
let camera = new THREE.PerspectiveCamera(50, 1, 0.05, 1000);
const controls = new OrbitControls(camera, canvas);
let gltfCameras = [];
let probes = null;
const originals = new Map(); // mesh -> its lit (Lambert) material

function resize() {
  const [w, h] = size || [window.innerWidth, window.innerHeight - 40];
  renderer.setSize(w, h, false);
  canvas.style.width = `${w}px`;
  canvas.style.height = `${h}px`;
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}

/** The lit material: Lambert, as radbake's convention (metallic ignored). */
function lambert(m) {
  return new THREE.MeshLambertMaterial({
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
  overlay.visible = state.view === 'probes' || overlay.userData.dynamic;
  for (const s of overlay.userData.spheres || []) s.visible = state.view === 'probes';
}

/** Vertex colours E/π(n) from an SH, per vertex (three.js's own SH evaluation). */
function shadeFromProbes(geometry, matrixWorld, shAt) {
  const pos = geometry.attributes.position;
  const nrm = geometry.attributes.normal;
  const colors = new Float32Array(pos.count * 3);
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
  geometry.setAttribute('color', new THREE.BufferAttribute(colors, 3));
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
      const at = probes.position(i);
      const sh = probes.probe(i).sh;
      g.translate(at.x, at.y, at.z);
      shadeFromProbes(g, new THREE.Matrix4(), () => sh);
      g.translate(-at.x, -at.y, -at.z);
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
    shadeFromProbes(g, o.matrixWorld, probes.shAt);
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

async function load(url) {
  const Plugin = params.get('loader') === 'hubs' ? HubsLightmapPlugin : RadbakeLightmapPlugin;
  const loader = new GLTFLoader().register((parser) => new Plugin(parser));
  const gltf = await loader.loadAsync(url);
  scene.clear();
  overlay.clear();
  originals.clear();
  // The glTF's punctual lights are baked into the lightmaps already: three's
  // GLTFLoader would add them as real-time lights and count them twice.
  const lights = [];
  gltf.scene.traverse((o) => o.isLight && lights.push(o));
  for (const l of lights) l.removeFromParent();
  scene.add(gltf.scene);
  gltf.scene.traverse((o) => {
    if (o.isMesh) {
      const lit = lambert(o.material);
      originals.set(o, lit);
    }
  });
  gltfCameras = gltf.cameras;
  window.radbake.cameras = gltfCameras.map((c) => c.name);
  probes = params.get('probes') ? await loadRadbakeProbes(params.get('probes')) : null;
  window.radbake.probes = probes ? probes.count : 0;
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
      controls.update();
      render();
    });
  })
  .catch((e) => {
    window.radbake.error = String(e);
    document.getElementById('status').textContent = `error: ${e}`;
  });
