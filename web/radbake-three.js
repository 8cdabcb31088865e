// radbake's outputs in three.js (r187): a GLTFLoader plugin for the baked
// `.glb`'s lightmaps, and the bake's light probes.
//
//   import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
//   import { RadbakeLightmapPlugin, loadRadbakeProbes } from './radbake-three.js';
//   const loader = new GLTFLoader().register((parser) => new RadbakeLightmapPlugin(parser));
//   const gltf = await loader.loadAsync('bake/scene.baked.glb');
//   scene.add(gltf.scene);
//   const probes = await loadRadbakeProbes('bake/probes.json');   // optional
//   scene.add(probes.lightProbeAt(character.position));             // a LightProbe
//
// Conventions (docs/engines.md, three.js): a lightmap texel holds incident
// irradiance / π as sRGB(value / s) with one scale s per instance, and
// `MOZ_lightmap.intensity` = π s. three.js takes `texel × lightMapIntensity`
// as irradiance and divides by π in the Lambert BRDF (and in
// MeshBasicMaterial's lightmap term), so with the texture marked sRGB the
// result is albedo × value: nothing else to scale. The stock Hubs-style
// loader reads the bytes as linear (NoColorSpace): that renders
// srgb(v / s) × s in place of v (too bright, most in the dark).

import * as THREE from 'three';

/**
 * `MOZ_lightmap` read onto `materialParams` with the texture in
 * `colorSpace`: `texCoord: 1` becomes texture.channel = 1 (uv1), the
 * instance's atlas rectangle (`KHR_texture_transform`) the texture's
 * transform, and `intensity` the lightMapIntensity.
 */
function assignLightmap(parser, materialIndex, materialParams, colorSpace) {
  const def = parser.json.materials[materialIndex];
  const ext = def.extensions && def.extensions.MOZ_lightmap;
  if (!ext) return Promise.resolve();
  const info = { index: ext.index, texCoord: ext.texCoord ?? 1, extensions: ext.extensions };
  materialParams.lightMapIntensity = ext.intensity ?? 1;
  return parser.assignTexture(materialParams, 'lightMap', info, colorSpace);
}

/** A GLTFLoader plugin for `MOZ_lightmap` as radbake writes it (sRGB). */
export class RadbakeLightmapPlugin {
  constructor(parser) {
    this.parser = parser;
    this.name = 'MOZ_lightmap';
  }

  extendMaterialParams(materialIndex, materialParams) {
    return assignLightmap(this.parser, materialIndex, materialParams, THREE.SRGBColorSpace);
  }
}

/**
 * The stock Hubs / ir-engine semantics for `MOZ_lightmap` (see
 * ../shared/ENGINES.md): the texture from `parser.getDependency('texture',
 * index)`, left NoColorSpace (bytes read as linear values), and
 * `lightMapIntensity = intensity`. Only for checking what those loaders
 * render; the atlas rectangle (`KHR_texture_transform`) is applied as
 * GLTFLoader does, so that only the colour space differs.
 */
export class HubsLightmapPlugin {
  constructor(parser) {
    this.parser = parser;
    this.name = 'MOZ_lightmap';
  }

  extendMaterialParams(materialIndex, materialParams) {
    return assignLightmap(this.parser, materialIndex, materialParams, THREE.NoColorSpace);
  }
}

/** The nine RGB radiance SH coefficients of probe `i` as a SphericalHarmonics3. */
function harmonics(floats, i) {
  const sh = new THREE.SphericalHarmonics3();
  for (let k = 0; k < 9; k++) {
    const o = i * 27 + 3 * k;
    sh.coefficients[k].set(floats[o], floats[o + 1], floats[o + 2]);
  }
  return sh;
}

/**
 * Loads `probes.json` and the binary it names. Returns
 * `{ meta, count, probe(i), position(i), shAt(p), lightProbeAt(p) }`:
 * `probe(i)` is a LightProbe for probe i; `shAt(p)` the SH interpolated
 * trilinearly between the eight probes around world point p (clamped to the
 * grid's outer probes, as Bevy samples its volume); `lightProbeAt(p)` a
 * LightProbe holding it, for a dynamic object standing at p.
 */
export async function loadRadbakeProbes(url) {
  const meta = await (await fetch(url)).json();
  const bin = await (await fetch(new URL(meta.binary, new URL(url, location.href)))).arrayBuffer();
  const floats = new Float32Array(bin);
  if (floats.length !== meta.probes * 27) {
    throw new Error(`${meta.binary}: ${floats.length / 27} probes, ${url} says ${meta.probes}`);
  }
  const volumes = meta.volumes.map((v) => {
    const m = new THREE.Matrix4().fromArray(v.world_from_box);
    return { ...v, matrix: m, inverse: m.clone().invert() };
  });
  const local = new THREE.Vector3();
  function volumeAt(p) {
    let best = null;
    let bestOut = Infinity;
    for (const v of volumes) {
      local.copy(p).applyMatrix4(v.inverse);
      const out = Math.max(Math.abs(local.x), Math.abs(local.y), Math.abs(local.z));
      if (out < bestOut) {
        bestOut = out;
        best = v;
      }
    }
    return best;
  }
  function position(i) {
    const v = volumes.find((v) => i >= v.first_probe && i < v.first_probe + v.probes);
    const [rx, ry] = v.resolution;
    const j = i - v.first_probe;
    const c = new THREE.Vector3(j % rx, Math.floor(j / rx) % ry, Math.floor(j / (rx * ry)));
    c.addScalar(0.5).divide(new THREE.Vector3(...v.resolution)).subScalar(0.5);
    return c.applyMatrix4(v.matrix);
  }
  function shAt(p) {
    const v = volumeAt(p);
    const r = new THREE.Vector3(...v.resolution);
    local.copy(p).applyMatrix4(v.inverse);
    const stp = local.addScalar(0.5).multiply(r);
    stp.clamp(new THREE.Vector3(0.5, 0.5, 0.5), r.clone().subScalar(0.5)).subScalar(0.5);
    const base = stp.clone().floor();
    const f = stp.clone().sub(base);
    const out = new THREE.SphericalHarmonics3();
    for (let corner = 0; corner < 8; corner++) {
      const o = [corner & 1, (corner >> 1) & 1, corner >> 2];
      const c = [0, 1, 2].map((a) => Math.min(base.getComponent(a) + o[a], v.resolution[a] - 1));
      const w = [0, 1, 2].reduce((acc, a) => acc * (o[a] ? f.getComponent(a) : 1 - f.getComponent(a)), 1);
      if (w === 0) continue;
      const i = v.first_probe + c[0] + v.resolution[0] * (c[1] + v.resolution[1] * c[2]);
      const sh = harmonics(floats, i);
      for (let k = 0; k < 9; k++) out.coefficients[k].addScaledVector(sh.coefficients[k], w);
    }
    return out;
  }
  return {
    meta,
    count: meta.probes,
    probe: (i) => new THREE.LightProbe(harmonics(floats, i), 1),
    position,
    shAt,
    lightProbeAt: (p) => new THREE.LightProbe(shAt(p), 1),
  };
}
