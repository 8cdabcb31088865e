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
//   const layers = await loadRadbakeLayers('bake/manifest.json', gltf.scene, probes);
//   layers.setLayerWeight('lamp', [2, 1.6, 1]);                     // optional
//   const live = await loadRadbakeLive('bake/manifest.json', layers); // a live bake (--live)
//   live.setSun([0.3, 0.8, 0.5]);                                    // its bounce light re-solved
//
// Conventions (docs/engines.md, three.js): a lightmap texel holds incident
// irradiance / π as sRGB(value / s) with one scale s per instance, and
// `MOZ_lightmap.intensity` = π s. three.js takes `texel × lightMapIntensity`
// as irradiance and divides by π in the Lambert BRDF (and in
// MeshBasicMaterial's lightmap term), so with the texture marked sRGB the
// result is albedo × value: nothing else to scale. The stock Hubs-style
// loader reads the bytes as linear (NoColorSpace): that renders
// srgb(v / s) × s in place of v (too bright, most in the dark).
//
// Light layers (docs/layers.md): `loadRadbakeLayers` replaces each
// lightmapped material's lightMap by a linear half-float page holding
// Σₖ wₖ × layer k (from the layers' `lightmap_<page>_<layer>.exr`), with
// the glb's atlas rectangle and uv1 kept and lightMapIntensity = π (the
// page holds irradiance / π unscaled), and rewrites the probes' SH to the
// same sum.
//
// Live radiosity (docs/live.md): `loadRadbakeLive` runs the live bake's
// solve (radbake-live.js, the Rust run time's port) for a new sun and puts
// its pages in place of the live layer's, so the lightmap becomes
// Σ_{k ≠ live} wₖ × layer k + the live pages, as `radbake relight` writes.

import * as THREE from 'three';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';

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
 * `{ meta, count, floats, probe(i), position(i), shAt(p), lightProbeAt(p) }`:
 * `floats` the coefficients (27 per probe: nine RGB radiance SH, as
 * `probes.bin`), which `loadRadbakeLayers` rewrites in place and every
 * later call reads; `probe(i)` is a LightProbe for probe i; `shAt(p)` the SH interpolated
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
    floats,
    probe: (i) => new THREE.LightProbe(harmonics(floats, i), 1),
    position,
    shAt,
    lightProbeAt: (p) => new THREE.LightProbe(shAt(p), 1),
  };
}

/**
 * Float32 to half float by table, indexed by the float's sign and
 * exponent (its top 9 bits): half = base[e] + (mantissa >> shift[e]), as
 * THREE.DataUtils.toHalfFloat but saturating at ±65504, the largest
 * finite half, in place of going infinite.
 */
const HALF = (() => {
  const base = new Uint16Array(512);
  const shift = new Uint8Array(512);
  for (let i = 0; i < 256; i++) {
    const e = i - 127;
    let b;
    let sh;
    if (e < -27) [b, sh] = [0, 24]; // to zero
    else if (e < -14) [b, sh] = [0x0400 >> (-e - 14), -e - 1]; // subnormal
    else if (e <= 15) [b, sh] = [(e + 15) << 10, 13];
    else if (e < 128) [b, sh] = [0x7bff, 24]; // too large: 65504
    else [b, sh] = [0x7c00, 13]; // infinity, NaN
    base[i] = b;
    base[i | 0x100] = b | 0x8000;
    shift[i] = shift[i | 0x100] = sh;
  }
  return { base, shift };
})();

/** Fetches `url` as an ArrayBuffer; a failed request is a one-line error naming it. */
async function fetchBytes(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
  return response.arrayBuffer();
}

/**
 * A layer's page from its EXR as packed linear RGB floats, rows in the
 * glb's order (row 0 at v = 0, the top of the image). EXRLoader returns
 * RGBA with its rows bottom-up.
 */
function readPage(url, bytes) {
  const { width, height, data } = new EXRLoader().setDataType(THREE.FloatType).parse(bytes);
  const rgb = new Float32Array(width * height * 3);
  for (let y = 0; y < height; y++) {
    const from = (height - 1 - y) * width * 4;
    const to = y * width * 3;
    for (let x = 0; x < width; x++) {
      rgb[to + 3 * x] = data[from + 4 * x];
      rgb[to + 3 * x + 1] = data[from + 4 * x + 1];
      rgb[to + 3 * x + 2] = data[from + 4 * x + 2];
    }
  }
  return { url, width, height, rgb };
}

/** An RGB weight from a number (grey) or three numbers; null if not one. */
function weightOf(value) {
  const rgb = typeof value === 'number' ? [value, value, value] : Array.isArray(value) && value.length === 3 ? value : null;
  return rgb && rgb.every((w) => typeof w === 'number' && Number.isFinite(w) && w >= 0) ? rgb : null;
}

/** sum += w ⊙ src, both packed RGB. */
function accumulate(sum, src, [r, g, b]) {
  for (let j = 0; j < sum.length; j += 3) {
    sum[j] += r * src[j];
    sum[j + 1] += g * src[j + 1];
    sum[j + 2] += b * src[j + 2];
  }
}

/** Packed RGB floats to RGBA half floats (alpha left as it is), rounded to nearest (+ half a half-float step). */
function toHalf(sum, out) {
  const { base, shift } = HALF;
  const bits = new Uint32Array(sum.buffer, sum.byteOffset, sum.length);
  // Unrolled over the channels: a loop over c here takes 1.6 × as long in V8.
  for (let j = 0, o = 0; j < bits.length; j += 3, o += 4) {
    let f = bits[j] + 0x1000;
    let e = (f >>> 23) & 0x1ff;
    out[o] = base[e] + ((f & 0x7fffff) >> shift[e]);
    f = bits[j + 1] + 0x1000;
    e = (f >>> 23) & 0x1ff;
    out[o + 1] = base[e] + ((f & 0x7fffff) >> shift[e]);
    f = bits[j + 2] + 0x1000;
    e = (f >>> 23) & 0x1ff;
    out[o + 2] = base[e] + ((f & 0x7fffff) >> shift[e]);
  }
}

/** sum = fixed + w ⊙ src, all packed RGB. */
function addTo(sum, fixed, src, [r, g, b]) {
  for (let j = 0; j < sum.length; j += 3) {
    sum[j] = fixed[j] + r * src[j];
    sum[j + 1] = fixed[j + 1] + g * src[j + 1];
    sum[j + 2] = fixed[j + 2] + b * src[j + 2];
  }
}

/**
 * Loads the light layers of the bake whose `manifest.json` is at
 * `manifestUrl` and makes the lightmapped materials under `root` (the
 * bake's `.glb` as RadbakeLightmapPlugin loaded it) show their weighted
 * sum Σₖ wₖ × layer k, every weight 1 at first (the bake's own lightmap).
 * Each material whose lightMap is the glb's texture `lightmap_<page>`
 * gets a linear half-float texture of that page, sharing one image per
 * page, with the old texture's uv channel and atlas transform and
 * lightMapIntensity = π; materials made later from these (clones, other
 * material types) follow the weights too. The emissive materials a
 * layer holds (the manifest's `materials`, by name) get their emissive
 * colour × w. Given the bake's `probes` (loadRadbakeProbes), their
 * coefficients become the same sum.
 *
 * Returns `{ names, weight(name), setLayerWeight(name, w),
 * setLayerWeights({ name: w, ... }), replaceLayer(name, pages, why),
 * page(index), cost }`: `names` the layers in the manifest's order (none
 * for a bake without layers); a weight `w` is a number or [r, g, b],
 * non-negative; layers not named keep theirs. Setting weights recombines
 * on the CPU at once; `cost` is `{ ms, texels }` of the last
 * recombination. An unknown layer or a bad weight is an error and changes
 * nothing. Half floats hold up to 65504: larger sums are stored as 65504.
 * `replaceLayer` gives one layer's pages at run time (loadRadbakeLive's
 * live layer; see there). `page(index)` is lightmap page `index` as
 * combined, before the half-float conversion: `{ width, height, rgb }`,
 * rgb packed linear RGB (irradiance / π), row 0 at v = 0, rewritten by
 * every recombination.
 */
export async function loadRadbakeLayers(manifestUrl, root, probes = null) {
  const base = new URL(manifestUrl, location.href);
  const manifest = await (await fetch(base)).json();
  const layers = manifest.layers || [];
  const names = layers.map((l) => l.name);
  const weights = new Map(names.map((n) => [n, [1, 1, 1]]));
  const pageIndices = (manifest.pages || []).map((p) => p.page);
  // layerPages[k].get(page): layer k's page as packed RGB.
  const layerPages = await Promise.all(
    layers.map(async (l) => {
      const pages = new Map();
      await Promise.all(
        pageIndices.map(async (page) => {
          const entry = l.pages.find((p) => p.page === page);
          if (!entry) throw new Error(`${manifestUrl}: layer ${l.name} has no page ${page}`);
          const url = new URL(entry.exr, base).href;
          pages.set(page, readPage(entry.exr, await fetchBytes(url)));
        }),
      );
      return pages;
    }),
  );
  const layerProbes = probes
    ? await Promise.all(
        layers.map(async (l) => {
          const floats = new Float32Array(await fetchBytes(new URL(l.probes.binary, base).href));
          if (floats.length !== probes.floats.length) {
            throw new Error(`${l.probes.binary}: ${floats.length / 27} probes, the bake has ${probes.count}`);
          }
          return floats;
        }),
      )
    : [];

  // One half-float image per page; a texture per material's lightMap.
  const combined = new Map();
  if (names.length) {
    for (const page of pageIndices) {
      const { width, height, url } = layerPages[0].get(page);
      for (const pages of layerPages) {
        const p = pages.get(page);
        if (p.width !== width || p.height !== height) {
          throw new Error(`${p.url}: ${p.width}×${p.height}, ${url} is ${width}×${height}`);
        }
      }
      const data = new Uint16Array(width * height * 4).fill(THREE.DataUtils.toHalfFloat(1));
      const texture = new THREE.DataTexture(data, width, height, THREE.RGBAFormat, THREE.HalfFloatType);
      texture.colorSpace = THREE.LinearSRGBColorSpace;
      texture.magFilter = THREE.LinearFilter;
      texture.minFilter = THREE.LinearFilter;
      texture.generateMipmaps = false;
      texture.flipY = false;
      combined.set(page, { texture, clones: [], sum: new Float32Array(width * height * 3) });
    }
  }
  const replaced = new Map(); // the glb's lightMap -> its layered texture
  let materials = 0;
  root.traverse((o) => {
    if (!o.isMesh || !names.length) return;
    for (const m of Array.isArray(o.material) ? o.material : [o.material]) {
      const old = m.lightMap;
      const page = old && /^lightmap_(\d+)$/.exec(old.name);
      if (!page || !combined.has(Number(page[1]))) continue;
      const target = combined.get(Number(page[1]));
      if (!replaced.has(old)) {
        const { width, height } = target.texture.image;
        if (old.image && (old.image.width !== width || old.image.height !== height)) {
          throw new Error(`the glb's ${old.name} is ${old.image.width}×${old.image.height}, its layers ${width}×${height}`);
        }
        const t = target.texture.clone();
        t.name = old.name;
        t.channel = old.channel;
        t.offset.copy(old.offset);
        t.repeat.copy(old.repeat);
        t.center.copy(old.center);
        t.rotation = old.rotation;
        t.matrixAutoUpdate = old.matrixAutoUpdate;
        t.matrix.copy(old.matrix);
        target.clones.push(t);
        replaced.set(old, t);
      }
      m.lightMap = replaced.get(old);
      m.lightMapIntensity = Math.PI;
      m.needsUpdate = true;
      materials++;
    }
  });
  if (names.length && !materials) {
    throw new Error(`${manifestUrl}: no material uses a lightmap_<page> texture of this bake`);
  }
  // The layers' emissive materials (by name): their emission at weight 1.
  const emitters = [];
  root.traverse((o) => {
    if (!o.isMesh) return;
    for (const m of Array.isArray(o.material) ? o.material : [o.material]) {
      const k = layers.findIndex((l) => (l.materials || []).includes(m.name));
      if (k >= 0 && m.emissive && !emitters.some((e) => e.material === m)) {
        emitters.push({ material: m, layer: k, emissive: m.emissive.clone() });
      }
    }
  });

  const cost = { ms: 0, texels: 0 };
  // The probes' sum over the layers but a replaced one's (null: to make).
  const probeSum = { others: null, r: -1 };
  // A layer whose pages are given at run time (`replaceLayer`: the live
  // layer): its index, why its weight is fixed, and per page the other
  // layers' weighted sum, recomputed only when a weight changes.
  let replacedLayer = null;

  /**
   * Writes Σₖ wₖ × layer k into every page, and with `all` the layers'
   * emission and the probes too; a replaced layer with a probe change
   * rewrites the probes at every refresh.
   */
  function recombine(all = true) {
    if (!names.length) return;
    const started = performance.now();
    const w = names.map((n) => weights.get(n));
    let texels = 0;
    for (const [page, { texture, clones, sum }] of combined) {
      const sources = layerPages.map((pages) => pages.get(page).rgb);
      if (replacedLayer) {
        const { k: r, fixed } = replacedLayer;
        const others = fixed.get(page);
        if (all || replacedLayer.stale) {
          others.fill(0);
          sources.forEach((src, k) => k !== r && accumulate(others, src, w[k]));
        }
        addTo(sum, others, sources[r], w[r]);
      } else {
        sum.fill(0);
        sources.forEach((src, k) => accumulate(sum, src, w[k]));
      }
      toHalf(sum, texture.image.data);
      texels += sum.length / 3;
      for (const t of clones) t.needsUpdate = true;
    }
    if (replacedLayer) replacedLayer.stale = false;
    if (all) {
      for (const { material, layer, emissive } of emitters) {
        const [r, g, b] = w[layer];
        material.emissive.setRGB(emissive.r * r, emissive.g * g, emissive.b * b);
      }
    }
    // The probes: every layer's at its weight, the replaced layer's moved
    // by its change (a live sun's, `refresh(delta)`).
    const delta = replacedLayer && replacedLayer.probeDelta;
    if (probes && (all || delta)) {
      const out = probes.floats;
      const r = delta ? replacedLayer.k : -1;
      // The other layers' sum is kept until a weight changes.
      if (all || !probeSum.others || probeSum.r !== r) {
        probeSum.others = new Float32Array(out.length);
        probeSum.r = r;
        layerProbes.forEach((src, k) => k !== r && accumulate(probeSum.others, src, w[k]));
      }
      if (r >= 0) {
        addTo(out, probeSum.others, layerProbes[r], w[r]);
        accumulate(out, delta, w[r]);
      } else {
        out.set(probeSum.others);
      }
    }
    cost.ms = performance.now() - started;
    cost.texels = texels;
  }

  /**
   * Layer `name`'s pages become `pages` (per page index, `{ width,
   * height, rgb }` with rgb packed linear RGB as the EXR pages: kept by
   * reference), recombined at once. With `why`, a weight for it is an
   * error saying so. Returns `refresh(probeDelta)`, which recombines the
   * pages after `pages` changed in place: the other layers' weighted sum
   * is kept between weight changes, so a refresh costs one add per texel
   * and the half-float conversion. `probeDelta` (27 floats per probe, as
   * `probes.bin`; null: none) is added to the layer's probes as baked.
   */
  function replaceLayer(name, pages, why = null) {
    const k = names.indexOf(known(name));
    for (const [page, { texture }] of combined) {
      const p = pages[page];
      const { width, height } = texture.image;
      if (!p || p.width !== width || p.height !== height || !(p.rgb instanceof Float32Array) || p.rgb.length !== width * height * 3) {
        throw new Error(`light layer ${name}: its page ${page} is not ${width}×${height} RGB floats`);
      }
    }
    for (const [page] of combined) layerPages[k].set(page, { url: `${name} (run time)`, ...pages[page] });
    const fixed = new Map([...combined].map(([page, { sum }]) => [page, new Float32Array(sum.length)]));
    replacedLayer = { k, name, why, fixed, stale: true, probeDelta: null };
    recombine();
    return (probeDelta = null) => {
      if (probeDelta && probes && probeDelta.length !== probes.floats.length) {
        throw new Error(`light layer ${name}: a probe change of ${probeDelta.length / 27} probes, the bake has ${probes.count}`);
      }
      replacedLayer.probeDelta = probes ? probeDelta : null;
      recombine(false);
    };
  }

  /** `name`, or an error naming it and the bake's layers. */
  function known(name) {
    if (!weights.has(name)) {
      throw new Error(`unknown light layer "${name}" (${names.length ? `this bake's: ${names.join(', ')}` : 'this bake has none'})`);
    }
    return name;
  }

  function setLayerWeights(changes) {
    const checked = Object.entries(changes).map(([name, value]) => {
      known(name);
      if (replacedLayer && replacedLayer.name === name && replacedLayer.why) throw new Error(`light layer ${name}: ${replacedLayer.why}`);
      const rgb = weightOf(value);
      if (!rgb) throw new Error(`light layer ${name}: weight ${JSON.stringify(value)} is not a non-negative number or [r, g, b]`);
      return [name, rgb];
    });
    for (const [name, rgb] of checked) weights.set(name, [...rgb]);
    recombine();
  }

  recombine();
  return {
    names,
    weight: (name) => [...weights.get(known(name))],
    setLayerWeight: (name, value) => setLayerWeights({ [name]: value }),
    setLayerWeights,
    replaceLayer,
    probes,
    page: (index) => {
      const c = combined.get(index);
      if (!c) throw new Error(`no lightmap page ${index} (this bake's: ${[...combined.keys()].join(', ') || 'none'})`);
      return { width: c.texture.image.width, height: c.texture.image.height, rgb: c.sum };
    },
    cost,
  };
}

/**
 * Live radiosity (docs/live.md) for the bake whose `manifest.json` is at
 * `manifestUrl`, on its `layers` (what loadRadbakeLayers returned for
 * the same bake). Fetches the manifest's `live` file (`live.bin`), reads
 * and checks it (radbake-live.js, loaded only here: a truncated or
 * corrupted file is an error naming it and the section), solves it for
 * `sun` (default: the live light as baked; a cold start, as `radbake
 * relight`) and puts its pages in place of the live layer's: the lightmap
 * becomes Σ_{k ≠ live} wₖ × layer k + the live pages, the other layers at
 * their weights, the sky's layer × new sky / baked sky per channel
 * (`sky`, setSky). With the bake's probes given to loadRadbakeLayers and
 * the probes' rays in `live.bin`, the live layer's probes move too: as
 * baked + the runtime's `probeDelta()`.
 *
 * Returns `{ light, lights, runtime, sun(), sky(), setSun(direction,
 * irradiance), setSuns(list), setSky(rgb), cost }`: `light` the live
 * light's name (`lights` all of them, as baked), `sun()` its current
 * `{ direction, irradiance }`, `sky()` the sky's radiance (null where the
 * sky has no layer of its own), `runtime` the RadbakeLive (its `pages`
 * the live layer's alone); `setSun` turns the light
 * (direction towards the sun, y up, any length > 0; `irradiance` [r, g,
 * b] W/m², left out: unchanged, at first as baked), solves from the last
 * solution and rewrites the pages; `setSuns` takes one `{ direction,
 * irradiance }` per live light; `setSky` the sky's radiance [r, g, b].
 * `cost` is `{ ms, iterations, residual, solve, pages, lightmap, probes }`
 * of the last update (ms: the whole; solve: D and the Jacobi iterations;
 * pages: the texels and the live pages; lightmap: the recombination into
 * the half-float pages, and the probes'; probes: their change). A zero-length or NaN direction, a bad irradiance or
 * sky is an error naming it and changes nothing.
 */
export async function loadRadbakeLive(manifestUrl, layers, { sun = null, sky = null } = {}) {
  const base = new URL(manifestUrl, location.href);
  const manifest = await (await fetch(base)).json();
  const entry = manifest.live;
  if (!entry || typeof entry.file !== 'string') {
    throw new Error(`${manifestUrl}: the bake has no live lights (no \`live\`): bake with --live or a light in mode \`live\``);
  }
  const { parseRadbakeLive, RadbakeLive } = await import('./radbake-live.js');
  const data = parseRadbakeLive(await fetchBytes(new URL(entry.file, base).href), entry.file);
  const runtime = new RadbakeLive(data);
  const h = data.header;
  if (!layers.names.includes(h.layer)) {
    throw new Error(`${entry.file}: its live layer "${h.layer}" is not among the bake's layers (${layers.names.join(', ') || 'none'})`);
  }
  const suns = h.lights.map((l) => ({ direction: [...l.direction], irradiance: [...l.irradiance] }));
  let skyNow = h.sky ? [...h.sky.radiance] : null;
  const cost = { ms: 0, iterations: 0, residual: 0, solve: 0, pages: 0, lightmap: 0, probes: 0 };
  let refresh = null;

  /** Solves for `list` (one { direction, irradiance? } per live light) and recombines. */
  function setSuns(list) {
    if (!Array.isArray(list)) throw new Error('setSuns: expected one { direction, irradiance } per live light');
    const next = list.map((s, i) => ({
      direction: s && s.direction,
      irradiance: (s && s.irradiance) ?? (suns[i] || {}).irradiance,
    }));
    const solved = runtime.update(next);
    next.forEach((s, i) => {
      suns[i] = { direction: [...s.direction], irradiance: [...s.irradiance] };
    });
    if (!refresh) refresh = layers.replaceLayer(h.layer, runtime.pages, "it is re-solved for the sun: give the sun's irradiance instead (setSun)");
    const t = performance.now();
    const delta = layers.probes ? runtime.probeDelta() : null;
    const probesMs = performance.now() - t;
    refresh(delta);
    Object.assign(cost, {
      ms: solved.ms + probesMs + layers.cost.ms,
      iterations: solved.iterations,
      residual: solved.residual,
      solve: solved.solveMs,
      pages: solved.pagesMs,
      lightmap: layers.cost.ms,
      probes: probesMs,
    });
    return { ...cost };
  }

  function setSun(direction, irradiance = undefined) {
    if (h.lights.length !== 1) throw new Error(`the bake has ${h.lights.length} live lights: give one sun each (setSuns)`);
    return setSuns([{ direction, irradiance }]);
  }

  /** The sky layer's weight for sky radiance `rgb`: new / baked per channel, as `radbake relight --sky`. */
  function setSky(rgb) {
    if (!h.sky) {
      throw new Error('sky: the bake\'s sky has no layer of its own (an HDRI, black, or shared with other lights): it cannot change colour');
    }
    if (!Array.isArray(rgb) || rgb.length !== 3 || !rgb.every((v) => typeof v === 'number' && Number.isFinite(v) && v >= 0)) {
      throw new Error(`sky ${JSON.stringify(rgb)}: must be three numbers, finite and ≥ 0`);
    }
    const baked = h.sky.radiance;
    if (baked.some((b, c) => b === 0 && rgb[c] > 0)) {
      throw new Error(`sky ${rgb.join(',')}: the baked sky ${baked.join(',')} is 0 in a channel it lights: bake with a sky that is not`);
    }
    layers.setLayerWeight(h.sky.layer, baked.map((b, c) => (b > 0 ? rgb[c] / b : 0)));
    skyNow = [...rgb];
  }

  if (sky) setSky(sky);
  if (sun) setSuns(h.lights.map((_, i) => (i === 0 ? sun : suns[i])));
  else setSuns(suns);
  return {
    light: h.lights[0].name,
    lights: h.lights,
    runtime,
    sun: () => ({ direction: [...suns[0].direction], irradiance: [...suns[0].irradiance] }),
    sky: () => (skyNow ? [...skyNow] : null),
    setSun,
    setSuns,
    setSky,
    cost,
  };
}
