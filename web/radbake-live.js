// radbake's live radiosity in JavaScript (docs/live.md): a live bake's
// `live.bin` read and solved again for any sun, as the Rust run time
// `radbake_live::Live` does (live/src/format.rs, solve.rs, directions.rs).
// No dependencies: plain ES module, typed arrays, one thread.
//
//   import { parseRadbakeLive, RadbakeLive } from './radbake-live.js';
//   const data = parseRadbakeLive(await (await fetch('bake/live.bin')).arrayBuffer(), 'live.bin');
//   const live = new RadbakeLive(data);
//   const { iterations, residual, ms } = live.update({ direction: [0.3, 0.8, 0.5], irradiance: [5, 4.75, 4.4] });
//   live.pages[0].rgb;   // the live layer's page 0: Float32Array RGB, row-major, row 0 at v = 0
//
// Each update: the patches' direct light D from the sun table (bilinear
// between four grid nodes, or two sun-path samples), Jacobi iterations
// L ← ρ ⊙ (D + F L) from the last L until Σ|ΔL| / Σ|L| is below the bake's
// tolerance, then the texels' bounce light F L reconstructed as the bake's
// first pass does and written to the pages, padding rings included.
// Texels hold incident irradiance / π, as every radbake lightmap.
//
// `radbake-three.js`'s `loadRadbakeLive` puts these pages into the light
// layers' recombination; this module knows nothing of three.js.

/** The file's first bytes: "RBLIVE\r\n". */
const MAGIC = [0x52, 0x42, 0x4c, 0x49, 0x56, 0x45, 0x0d, 0x0a];
/** The format version read here (live/src/format.rs `VERSION`). */
export const LIVE_VERSION = 2;
/** Largest patch or texel count accepted (2²⁸), as the Rust reader. */
const MAX_COUNT = 2 ** 28;
/** A texel's missing corner patch (u32::MAX). */
const NONE = 0xffffffff;

/**
 * CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, as crc32fast),
 * slicing by 8: table[k · 256 + b] is the CRC of byte b followed by k
 * zero bytes.
 */
const CRC_TABLE = (() => {
  const t = new Uint32Array(8 * 256);
  for (let b = 0; b < 256; b++) {
    let c = b;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    t[b] = c;
  }
  for (let b = 0; b < 256; b++) {
    for (let k = 1; k < 8; k++) t[k * 256 + b] = (t[(k - 1) * 256 + b] >>> 8) ^ t[t[(k - 1) * 256 + b] & 0xff];
  }
  return t;
})();

/** CRC-32 of `bytes` (a Uint8Array). */
export function crc32(bytes) {
  const t = CRC_TABLE;
  let c = 0xffffffff;
  let i = 0;
  const n = bytes.length;
  for (; i + 8 <= n; i += 8) {
    const a = c ^ (bytes[i] | (bytes[i + 1] << 8) | (bytes[i + 2] << 16) | (bytes[i + 3] << 24));
    c =
      t[7 * 256 + (a & 0xff)] ^
      t[6 * 256 + ((a >>> 8) & 0xff)] ^
      t[5 * 256 + ((a >>> 16) & 0xff)] ^
      t[4 * 256 + (a >>> 24)] ^
      t[3 * 256 + bytes[i + 4]] ^
      t[2 * 256 + bytes[i + 5]] ^
      t[256 + bytes[i + 6]] ^
      t[bytes[i + 7]];
  }
  for (; i < n; i++) c = t[(c ^ bytes[i]) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

/** Every f16 bit pattern as a number (Float32Array of 65536). */
const HALF_TO_FLOAT = (() => {
  const out = new Float32Array(65536);
  for (let h = 0; h < 65536; h++) {
    const e = (h >>> 10) & 0x1f;
    const m = h & 0x3ff;
    const v = e === 0 ? m * 2 ** -24 : e === 31 ? (m ? NaN : Infinity) : (1 + m / 1024) * 2 ** (e - 15);
    out[h] = h & 0x8000 ? -v : v;
  }
  return out;
})();

/** The body's sections in file order: name, bytes per unit, units for header `h`. */
function sections(h) {
  const dirs = h.lights.reduce((a, l) => a + directionCount(l, h.grid), 0);
  const padding = h.padding.reduce((a, b) => a + b, 0);
  return [
    ['albedo', 12, h.patches],
    ["F's rows", 4, h.patches + 1],
    ["F's columns", 4, h.entries],
    ["F's entries", 2, h.entries],
    ['sun table', 1, dirs * h.patches],
    ["texels' patches", 4, h.texels],
    ["texels' shares", 4, h.texels],
    ["texels' corners", 16, h.texels],
    ["texels' pixels", 4, h.texels],
    ["texels' pages", 2, h.texels],
    ['padding', 5, padding],
    ["probes' validity", 1, h.probes ? h.probes.count : 0],
    ["probes' ray hits", 4, h.probes ? h.probes.count * h.probes.rays : 0],
    ["patches' baked radiance", 12, h.probes ? h.patches : 0],
  ];
}

/** How many directions a live light's sun table holds: its path's samples, or grid². */
function directionCount(light, grid) {
  return light.path ? light.path.length : grid * grid;
}

const isCount = (v) => Number.isSafeInteger(v) && v >= 0;
const isVec3 = (v) => Array.isArray(v) && v.length === 3 && v.every((x) => typeof x === 'number' && Number.isFinite(x));

/**
 * The header's fields checked as serde does for the Rust `Header`
 * (`deny_unknown_fields`, every field typed) and then as `check_header`
 * does; the first problem as a message, or null.
 */
function headerProblem(h) {
  if (!h || typeof h !== 'object' || Array.isArray(h)) return 'header: not a JSON object';
  const fields = ['version', 'patches', 'texels', 'entries', 'block', 'grid', 'pages', 'padding', 'tolerance', 'max_iterations', 'layer', 'lights', 'sky', 'probes'];
  const unknown = Object.keys(h).find((k) => !fields.includes(k));
  if (unknown) return `header: unknown field \`${unknown}\``;
  for (const k of ['version', 'patches', 'texels', 'entries', 'block', 'grid', 'max_iterations']) {
    if (!isCount(h[k])) return `header: \`${k}\` is not a non-negative integer`;
  }
  if (typeof h.tolerance !== 'number') return 'header: `tolerance` is not a number';
  if (typeof h.layer !== 'string') return 'header: `layer` is not a string';
  if (!Array.isArray(h.pages) || !h.pages.every((p) => p && isCount(p.width) && isCount(p.height))) return 'header: `pages` is not a list of { width, height }';
  if (!Array.isArray(h.padding) || !h.padding.every(isCount)) return 'header: `padding` is not a list of counts';
  if (!Array.isArray(h.lights)) return 'header: `lights` is not a list';
  for (const l of h.lights) {
    if (!l || typeof l.name !== 'string' || !Array.isArray(l.direction) || !Array.isArray(l.irradiance)) return 'header: a live light lacks its name, direction or irradiance';
    if (l.path != null && !Array.isArray(l.path)) return 'header: a live light\'s `path` is not a list';
  }
  if (h.sky != null && (typeof h.sky.layer !== 'string' || !Array.isArray(h.sky.radiance))) return 'header: `sky` is not { layer, radiance }';
  if (h.probes != null) {
    const q = h.probes;
    const gridOk = (g) => g && isCount(g.first) && Array.isArray(g.resolution) && g.resolution.length === 3 && g.resolution.every(isCount);
    if (typeof q !== 'object' || !isCount(q.count) || !isCount(q.rays) || !Array.isArray(q.grids) || !q.grids.every(gridOk)) {
      return 'header: `probes` is not { count, rays, grids: [{ first, resolution }] }';
    }
  }
  // check_header's ranges.
  if (h.patches > MAX_COUNT || h.texels > MAX_COUNT || h.padding.some((n) => n > 2 ** 30)) return 'patch, texel or padding count out of range';
  if (h.entries > 0xffffffff) return "F's entry count out of range";
  if (h.grid < 2 || h.grid > 64 || h.block < 1 || h.block > 64) return `grid ${h.grid} or block ${h.block} out of range`;
  if (!h.lights.length) return 'no live light';
  if (!h.lights.every((l) => isVec3(l.direction) && isVec3(l.irradiance))) return "a live light's direction or irradiance is not finite";
  if (h.lights.some((l) => l.path != null && !(l.path.length >= 1 && l.path.length <= 4096 && l.path.every(isVec3)))) {
    return "a live light's sun path is empty, too long or not finite";
  }
  if (!(Number.isFinite(h.tolerance) && h.tolerance > 0) || h.max_iterations === 0) return 'solver tolerance or iteration limit out of range';
  const pageOk = (p) => p.width >= 1 && p.width <= 2 ** 15 && p.height >= 1 && p.height <= 2 ** 15;
  if (!h.pages.length || h.pages.length > 0xffff || !h.pages.every(pageOk)) return 'no pages, or a page size out of range';
  if (h.padding.length !== h.pages.length) return 'the padding counts do not match the pages';
  if (h.sky != null && !isVec3(h.sky.radiance)) return "the sky layer's radiance is not three finite numbers";
  if (h.lights.some((l) => l.direction.every((x) => x === 0))) return "a live light's direction is of zero length";
  if (h.probes != null) {
    const q = h.probes;
    if (q.count > MAX_COUNT || q.rays < 1 || q.rays > 4096) return 'probe count or rays per probe out of range';
    let next = 0;
    for (const g of q.grids) {
      const n = g.resolution[0] * g.resolution[1] * g.resolution[2];
      if (g.first !== next || n === 0 || n > MAX_COUNT) return 'the probe grids do not cover the probes in order';
      next += n;
    }
    if (next !== q.count) return `the probe grids hold ${next} probes, the header says ${q.count}`;
  }
  return null;
}

/**
 * Parses and checks a `live.bin` (live/src/format.rs): magic, version,
 * JSON header, the body's length against the header's counts, its CRC-32,
 * then every index and value as the Rust reader checks them. `name`
 * (the file's name or URL) starts every error message; a truncated or
 * corrupted file is an Error naming the section, never a wrong image.
 *
 * Returns `{ header, albedo, rows, cols, vals, suns, patch, share,
 * corners, pixel, page, padding }`: typed arrays (`vals` F's entries
 * decoded from f16 to a Float32Array once; `suns` one Uint8Array per live
 * light, directions × patches; `padding` per page a { pixel: Uint32Array,
 * neighbour: Uint8Array }).
 */
export function parseRadbakeLive(buffer, name = 'live.bin') {
  const fail = (message) => {
    throw new Error(`${name}: ${message}`);
  };
  const bytes = buffer instanceof Uint8Array ? buffer : new Uint8Array(buffer);
  if (new Uint8Array(new Uint32Array([1]).buffer)[0] !== 1) fail('this reader needs a little-endian machine');
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let at = 0;
  const take = (n, what) => {
    if (at + n > bytes.length) fail(`truncated in its ${what}`);
    const start = at;
    at += n;
    return start;
  };
  const u32 = (what) => view.getUint32(take(4, what), true);
  const m = take(8, 'magic');
  if (MAGIC.some((b, i) => bytes[m + i] !== b)) fail('not a radbake live file (wrong magic bytes)');
  const version = u32('version');
  if (version !== LIVE_VERSION) fail(`format version ${version}, this reader reads version ${LIVE_VERSION}: bake again`);
  const len = u32('header length');
  const hs = take(len, 'header');
  let header;
  try {
    header = JSON.parse(new TextDecoder('utf-8', { fatal: true }).decode(bytes.subarray(hs, hs + len)));
  } catch (e) {
    fail(`header: ${e.message}`);
  }
  const problem = headerProblem(header);
  if (problem) fail(problem);
  header.sky = header.sky ?? null;
  header.probes = header.probes ?? null;
  for (const l of header.lights) l.path = l.path ?? null;
  const crc = u32('checksum');
  const parts = sections(header);
  const want = parts.reduce((a, [, size, count]) => a + size * count, 0);
  const bodyLen = bytes.length - at;
  if (bodyLen !== want) {
    // The section the body ends in (or that the extra bytes follow).
    let end = 0;
    let where = 'padding';
    for (const [what, size, count] of parts) {
      end += size * count;
      if (bodyLen < end) {
        where = what;
        break;
      }
    }
    fail(`body is ${bodyLen} bytes, the header's counts give ${want} (${bodyLen < want ? `truncated in its ${where}` : 'padded after its last section'})`);
  }
  const raw = bytes.subarray(at);
  if (crc32(raw) !== crc) fail('checksum mismatch: the file is corrupted');
  // One aligned copy of the body, so that every section is a typed-array view.
  const body = raw.slice();
  const b = body.buffer;
  let off = 0;
  const section = (size, count) => {
    const start = off;
    off += size * count;
    return start;
  };
  const u32s = (count) => {
    const s = section(4, count);
    return s % 4 === 0 ? new Uint32Array(b, s, count) : new Uint32Array(b.slice(s, s + 4 * count));
  };
  const u16s = (count) => {
    const s = section(2, count);
    return s % 2 === 0 ? new Uint16Array(b, s, count) : new Uint16Array(b.slice(s, s + 2 * count));
  };
  // f32 sections: the same bytes as u32s, copied out and read as floats.
  const f32s = (count) => {
    const v = u32s(count);
    return new Float32Array(v.buffer.slice(v.byteOffset, v.byteOffset + 4 * count));
  };
  const h = header;
  const P = h.patches;
  const T = h.texels;
  const albedo = f32s(3 * P);
  const rows = u32s(P + 1);
  const cols = u32s(h.entries);
  const halves = u16s(h.entries);
  const suns = h.lights.map((l) => {
    const n = directionCount(l, h.grid) * P;
    const s = section(1, n);
    return body.subarray(s, s + n);
  });
  const patch = u32s(T);
  const share = f32s(T);
  const corners = u32s(4 * T);
  const pixel = u32s(T);
  const page = u16s(T);
  const padding = h.padding.map((n) => {
    const s = section(5, n);
    const pixels = new Uint32Array(n);
    const neighbour = new Uint8Array(n);
    for (let k = 0, o = s; k < n; k++, o += 5) {
      pixels[k] = body[o] | (body[o + 1] << 8) | (body[o + 2] << 16) | (body[o + 3] << 24);
      neighbour[k] = body[o + 4];
    }
    return { pixel: pixels, neighbour };
  });
  let probes = null;
  if (h.probes) {
    const s = section(1, h.probes.count);
    const valid = body.subarray(s, s + h.probes.count);
    const hits = u32s(h.probes.count * h.probes.rays);
    probes = { valid, hits, baked: f32s(3 * P) };
  }

  // check_body: every index within its range, every value finite.
  for (let i = 0; i < albedo.length; i++) {
    const a = albedo[i];
    if (!(Number.isFinite(a) && a >= 0)) fail('an albedo negative or not finite');
  }
  if (rows[0] !== 0 || rows[P] !== h.entries) fail("F's row starts do not rise from 0 to its entry count");
  for (let i = 0; i < P; i++) {
    const lo = rows[i];
    const hi = rows[i + 1];
    if (lo > hi) fail("F's row starts do not rise from 0 to its entry count");
  }
  for (let i = 0; i < P; i++) {
    const hi = rows[i + 1];
    for (let e = rows[i]; e < hi; e++) {
      if (cols[e] >= P || (e > rows[i] && cols[e - 1] >= cols[e])) fail(`F's row ${i}: columns out of order or range`);
    }
  }
  const vals = new Float32Array(h.entries);
  for (let e = 0; e < vals.length; e++) {
    const bits = halves[e];
    // Infinite or NaN (exponent all ones), or negative (−0 is allowed).
    if ((bits & 0x7c00) === 0x7c00 || (bits & 0x8000 && bits & 0x7fff)) fail('an entry of F is negative or not finite');
    vals[e] = HALF_TO_FLOAT[bits];
  }
  for (let t = 0; t < T; t++) if (patch[t] >= P) fail("a texel's patch out of range");
  for (let t = 0; t < T; t++) {
    const s = share[t];
    if (!(s >= 0 && s <= 1.0001)) fail("a texel's area share outside [0, 1]");
  }
  for (let k = 0; k < corners.length; k++) {
    const q = corners[k];
    if (q !== NONE && q >= P) fail("a texel's corner patch out of range");
  }
  const sizes = h.pages.map((s) => s.width * s.height);
  for (let t = 0; t < T; t++) {
    if (page[t] >= sizes.length || pixel[t] >= sizes[page[t]]) fail("a texel's pixel out of its page");
  }
  padding.forEach(({ pixel: pixels, neighbour }, pg) => {
    const { width: w, height: hgt } = h.pages[pg];
    for (let k = 0; k < pixels.length; k++) {
      const i = pixels[k];
      const n = neighbour[k];
      const x = (i % w) + ((n % 3) - 1);
      const y = Math.floor(i / w) + (Math.floor(n / 3) - 1);
      if (i >= sizes[pg] || n > 8 || x < 0 || x >= w || y < 0 || y >= hgt) fail('a padding pixel or its neighbour out of its page');
    }
  });
  if (probes) {
    const hits = probes.hits;
    for (let k = 0; k < hits.length; k++) {
      if (hits[k] !== NONE && hits[k] >= P) fail("a probe ray's patch out of range");
    }
    if (!probes.baked.every(Number.isFinite)) fail("a patch's baked radiance is not finite");
  }
  return { name, header, albedo, rows, cols, vals, suns, patch, share, corners, pixel, page, padding, probes };
}

// The sun directions (live/src/directions.rs): a grid × grid
// hemi-octahedral grid over the upper hemisphere (y up), or a sun path.

/** The direction at (u, v) ∈ [−1, 1]² of the hemi-octahedral square. */
export function fromSquare(u, v) {
  const x = (u + v) * 0.5;
  const z = (u - v) * 0.5;
  const y = Math.max(1 - Math.abs(x) - Math.abs(z), 0);
  const len = Math.hypot(x, y, z);
  return [x / len, y / len, z / len];
}

/** (u, v) ∈ [−1, 1]² of a unit direction with y ≥ 0 (the inverse of fromSquare). */
export function toSquare(d) {
  const s = Math.abs(d[0]) + Math.abs(d[1]) + Math.abs(d[2]);
  const x = d[0] / s;
  const z = d[2] / s;
  return [x + z, x - z];
}

/** Direction of grid node (i, j) of an n × n grid. */
export function nodeDirection(n, i, j) {
  const s = n - 1;
  return fromSquare(-1 + (2 * i) / s, -1 + (2 * j) / s);
}

/**
 * The four grid nodes around unit direction `d` and their bilinear
 * weights, as [[node j·n + i, weight], …]; null for a sun below the
 * horizon (y < 0), which lights nothing.
 */
export function gridWeights(n, d) {
  if (d[1] < 0) return null;
  const [u, v] = toSquare(d);
  const s = n - 1;
  const fu = Math.min(Math.max((u + 1) * 0.5 * s, 0), s);
  const fv = Math.min(Math.max((v + 1) * 0.5 * s, 0), s);
  const i0 = Math.min(Math.floor(fu), n - 2);
  const j0 = Math.min(Math.floor(fv), n - 2);
  const wu = fu - i0;
  const wv = fv - j0;
  const at = (i, j) => j * n + i;
  return [
    [at(i0, j0), (1 - wu) * (1 - wv)],
    [at(i0 + 1, j0), wu * (1 - wv)],
    [at(i0, j0 + 1), (1 - wu) * wv],
    [at(i0 + 1, j0 + 1), wu * wv],
  ];
}

/**
 * The sun `path`'s point nearest to unit direction `d` (by chord
 * distance): its segment k and the place t ∈ [0, 1] along it, as
 * { k, t }; null for a sun below the horizon.
 */
export function nearestOnPath(path, d) {
  if (d[1] < 0 || !path.length) return null;
  if (path.length === 1) return { k: 0, t: 0 };
  let best = Infinity;
  let bk = 0;
  let bt = 0;
  for (let k = 0; k + 1 < path.length; k++) {
    const a = path[k];
    const b = path[k + 1];
    const ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    const len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    const t = len2 > 0 ? Math.min(Math.max(((d[0] - a[0]) * ab[0] + (d[1] - a[1]) * ab[1] + (d[2] - a[2]) * ab[2]) / len2, 0), 1) : 0;
    const e = [d[0] - a[0] - t * ab[0], d[1] - a[1] - t * ab[1], d[2] - a[2] - t * ab[2]];
    const dist = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
    if (dist < best) {
      best = dist;
      bk = k;
      bt = t;
    }
  }
  return { k: bk, t: bt };
}

/** The two path samples around `d` and their weights, as pathWeights in directions.rs; null below the horizon. */
export function pathWeights(path, d) {
  const p = nearestOnPath(path, d);
  if (!p) return null;
  if (path.length === 1) return [[0, 1], [0, 0]];
  return [[p.k, 1 - p.t], [p.k + 1, p.t]];
}

/** The unit direction of `sun`, checking it and its irradiance as the Rust `Sun::unit`. */
function unitOf(sun) {
  const d = sun && sun.direction;
  const e = sun && sun.irradiance;
  const show = (v) => JSON.stringify(Array.isArray(v) ? v.map((x) => (Number.isFinite(x) ? x : String(x))) : v);
  if (!Array.isArray(d) || d.length !== 3 || !d.every((x) => typeof x === 'number')) {
    throw new Error(`sun direction ${show(d)}: expected [x, y, z]`);
  }
  const len = Math.hypot(d[0], d[1], d[2]);
  if (!Number.isFinite(len) || len < 1e-12) throw new Error(`sun direction ${show(d)}: of zero length or not finite`);
  if (!Array.isArray(e) || e.length !== 3 || !e.every((x) => typeof x === 'number' && Number.isFinite(x) && x >= 0)) {
    throw new Error(`sun irradiance ${show(e)}: must be three numbers, finite and ≥ 0`);
  }
  return [d[0] / len, d[1] / len, d[2] / len];
}

/**
 * A live bake at run time (the Rust `Live`): the parsed file, the current
 * solution (zero before the first update) and the live layer's pages.
 *
 * `pages`: per lightmap page `{ width, height, rgb }`, rgb a Float32Array
 * of width × height × 3 (row-major, row 0 at v = 0, as the layers' EXR
 * pages read by radbake-three.js), rewritten in place by every update.
 * `lights` the live lights as baked ({ name, direction, irradiance, path }).
 */
export class RadbakeLive {
  constructor(data) {
    const h = data.header;
    this.data = data;
    this.header = h;
    this.lights = h.lights;
    const P = h.patches;
    const T = h.texels;
    /** F's columns × 3: where each entry's patch starts in an RGB-interleaved array. */
    this.columns = new Int32Array(data.cols.length);
    for (let e = 0; e < data.cols.length; e++) this.columns[e] = 3 * data.cols[e];
    /** Per patch, RGB interleaved: D (irradiance / π), L, F L. */
    this.direct = new Float32Array(3 * P);
    this.radiance = new Float32Array(3 * P);
    this.indirect = new Float32Array(3 * P);
    // Per texel: its four corners' patches (× 3, into RGB-interleaved
    // arrays) and bilinear weights, normalised over the corners present; a
    // texel with none takes its own patch at weight 1. A missing corner is
    // patch 0 at weight 0.
    const corners = new Int32Array(4 * T);
    const weights = new Float32Array(4 * T);
    const k = h.block;
    for (let t = 0; t < T; t++) {
      const width = h.pages[data.page[t]].width;
      const x = data.pixel[t] % width;
      const y = Math.floor(data.pixel[t] / width);
      // As the bake: f = (xy + ½) / k − ½, w = f − ⌊f⌋ (in f32).
      const fx = Math.fround(Math.fround(Math.fround(x + 0.5) / k) - 0.5);
      const fy = Math.fround(Math.fround(Math.fround(y + 0.5) / k) - 0.5);
      const wx = Math.fround(fx - Math.floor(fx));
      const wy = Math.fround(fy - Math.floor(fy));
      const w = [(1 - wx) * (1 - wy), wx * (1 - wy), (1 - wx) * wy, wx * wy].map(Math.fround);
      let sum = 0;
      for (let c = 0; c < 4; c++) if (data.corners[4 * t + c] !== NONE) sum += w[c];
      for (let c = 0; c < 4; c++) {
        const q = data.corners[4 * t + c];
        corners[4 * t + c] = q === NONE ? 0 : 3 * q;
        weights[4 * t + c] = q !== NONE && sum > 0 ? w[c] / sum : 0;
      }
      if (!(weights[4 * t] > 0 || weights[4 * t + 1] > 0 || weights[4 * t + 2] > 0 || weights[4 * t + 3] > 0)) {
        corners[4 * t] = 3 * data.patch[t];
        weights[4 * t] = 1;
        weights[4 * t + 1] = weights[4 * t + 2] = weights[4 * t + 3] = 0;
      }
    }
    this.corners = corners;
    this.weights = weights;
    /** Per texel, its patch × 3. */
    this.patch3 = new Int32Array(T);
    for (let t = 0; t < T; t++) this.patch3[t] = 3 * data.patch[t];
    /** Per texel: the bilinear value, then its final value (RGB). */
    this.bilinear = new Float32Array(3 * T);
    this.texelValues = new Float32Array(3 * T);
    /** Per patch: its texels' area-weighted mean of the bilinear value. */
    this.mean = new Float64Array(3 * P);
    // Per page, the pixels shown and the texel each shows: its own, or for
    // a padding pixel its neighbour's, resolved in ring order at load.
    this.pages = [];
    this.shown = [];
    h.pages.forEach(({ width, height }, pg) => {
      const source = new Int32Array(width * height).fill(-1);
      for (let t = 0; t < T; t++) if (data.page[t] === pg) source[data.pixel[t]] = t;
      const { pixel, neighbour } = data.padding[pg];
      for (let q = 0; q < pixel.length; q++) {
        const n = neighbour[q];
        const from = pixel[q] + (Math.floor(n / 3) - 1) * width + ((n % 3) - 1);
        source[pixel[q]] = source[from];
      }
      let count = 0;
      for (let i = 0; i < source.length; i++) if (source[i] >= 0) count++;
      const pixels = new Uint32Array(count);
      const texels = new Uint32Array(count);
      for (let i = 0, o = 0; i < source.length; i++) {
        if (source[i] >= 0) {
          pixels[o] = i;
          texels[o++] = source[i];
        }
      }
      this.shown.push({ pixels, texels });
      this.pages.push({ width, height, rgb: new Float32Array(width * height * 3) });
    });
    /** What the last update did. */
    this.last = { iterations: 0, residual: 0, ms: 0, solveMs: 0, pagesMs: 0 };
  }

  /**
   * Sets the live lights (a sun `{ direction: [x, y, z], irradiance:
   * [r, g, b] }`, or a list of them, one per live light in order;
   * `irradiance` left out: as baked), solves to the bake's tolerance from
   * the last solution and rewrites `pages`. A direction is towards the
   * sun, y up, any length > 0; a sun below the horizon lights nothing.
   * Returns `{ iterations, residual, ms }` (ms: the whole update; also
   * `solveMs`, `pagesMs`). A zero-length or NaN direction, a bad
   * irradiance or the wrong number of suns is an Error naming it, and
   * changes nothing.
   */
  update(suns) {
    const started = performance.now();
    this.setSuns(suns);
    const solved = this.solve(this.header.max_iterations);
    const mid = performance.now();
    this.writePages();
    const done = performance.now();
    this.last = { ...solved, ms: done - started, solveMs: mid - started, pagesMs: done - mid };
    return this.last;
  }

  /** D for `suns` (as `update` takes them): per patch, Σ over the lights of E × the table's values at the directions around the sun, weighted. */
  setSuns(suns) {
    const h = this.header;
    const list = Array.isArray(suns) ? suns : [suns];
    if (list.length !== h.lights.length) {
      throw new Error(`${list.length} sun(s) given, the bake has ${h.lights.length} live light(s)`);
    }
    const P = h.patches;
    const terms = [];
    list.forEach((given, l) => {
      const light = h.lights[l];
      const sun = { direction: given && given.direction, irradiance: (given && given.irradiance) ?? light.irradiance };
      const d = unitOf(sun);
      const w = light.path ? pathWeights(light.path, d) : gridWeights(h.grid, d);
      if (!w) return;
      // Table bytes are π D × 255 for a unit sun.
      const scale = sun.irradiance.map((e) => Math.fround(e / Math.fround(255 * Math.PI)));
      for (const [k, wk] of w) {
        if (wk > 0) terms.push({ table: this.data.suns[l].subarray(k * P, (k + 1) * P), w: Math.fround(wk), scale });
      }
    });
    const out = this.direct;
    out.fill(0);
    for (const { table, w, scale } of terms) {
      const [r, g, b] = scale;
      for (let i = 0, o = 0; i < P; i++, o += 3) {
        const x = table[i] * w;
        out[o] += x * r;
        out[o + 1] += x * g;
        out[o + 2] += x * b;
      }
    }
  }

  /** out ← F x (RGB interleaved per patch), rows summed in column order. */
  product(x, out) {
    const { rows, vals } = this.data;
    const columns = this.columns;
    const P = this.header.patches;
    let lo = rows[0];
    for (let i = 0, o = 0; i < P; i++, o += 3) {
      const hi = rows[i + 1];
      let r = 0;
      let g = 0;
      let b = 0;
      for (let e = lo; e < hi; e++) {
        const f = vals[e];
        const j = columns[e];
        r += f * x[j];
        g += f * x[j + 1];
        b += f * x[j + 2];
      }
      out[o] = r;
      out[o + 1] = g;
      out[o + 2] = b;
      lo = hi;
    }
  }

  /**
   * Jacobi iterations L ← ρ ⊙ (D + F L) from the current L until
   * Σ|ΔL| / Σ|L| is below the bake's tolerance, at most `maxIterations`.
   * F L of the current L is kept between solves (zero with L at the
   * start), so each iteration is one product, as in the Rust `solve`.
   * Returns { iterations, residual }.
   */
  solve(maxIterations) {
    const tolerance = this.header.tolerance;
    const L = this.radiance;
    const D = this.direct;
    const FL = this.indirect;
    const rho = this.data.albedo;
    let iterations = 0;
    let residual = 0;
    while (iterations < maxIterations) {
      let change = 0;
      let total = 0;
      for (let i = 0; i < L.length; i++) {
        const next = Math.fround(rho[i] * (D[i] + FL[i]));
        change += Math.abs(next - L[i]);
        total += Math.abs(next);
        L[i] = next;
      }
      residual = total > 0 ? change / total : 0;
      this.product(L, FL);
      iterations++;
      if (residual < tolerance) break;
    }
    return { iterations, residual };
  }

  /**
   * The texels' bounce light from the patches' F L (the bake's first
   * pass): bilinear between the patches at the texel's corners, shifted
   * per patch so that the patch keeps its mean, clamped at 0; then each
   * page's pixels from their texels (the padding as copies).
   */
  writePages() {
    const T = this.header.texels;
    const P = this.header.patches;
    const values = this.indirect;
    const { corners, weights, bilinear, texelValues, mean, patch3 } = this;
    const share = this.data.share;
    mean.fill(0);
    for (let t = 0, c = 0, o = 0; t < T; t++, c += 4, o += 3) {
      const q0 = corners[c];
      const q1 = corners[c + 1];
      const q2 = corners[c + 2];
      const q3 = corners[c + 3];
      const w0 = weights[c];
      const w1 = weights[c + 1];
      const w2 = weights[c + 2];
      const w3 = weights[c + 3];
      const r = values[q0] * w0 + values[q1] * w1 + values[q2] * w2 + values[q3] * w3;
      const g = values[q0 + 1] * w0 + values[q1 + 1] * w1 + values[q2 + 1] * w2 + values[q3 + 1] * w3;
      const b = values[q0 + 2] * w0 + values[q1 + 2] * w1 + values[q2 + 2] * w2 + values[q3 + 2] * w3;
      bilinear[o] = r;
      bilinear[o + 1] = g;
      bilinear[o + 2] = b;
      const p = patch3[t];
      const s = share[t];
      mean[p] += bilinear[o] * s;
      mean[p + 1] += bilinear[o + 1] * s;
      mean[p + 2] += bilinear[o + 2] * s;
    }
    // Each patch's shift (its value less its texels' mean), into `mean`.
    for (let i = 0; i < 3 * P; i++) mean[i] = values[i] - mean[i];
    for (let t = 0, o = 0; t < T; t++, o += 3) {
      const p = patch3[t];
      texelValues[o] = Math.max(bilinear[o] + mean[p], 0);
      texelValues[o + 1] = Math.max(bilinear[o + 1] + mean[p + 1], 0);
      texelValues[o + 2] = Math.max(bilinear[o + 2] + mean[p + 2], 0);
    }
    for (let pg = 0; pg < this.pages.length; pg++) {
      const rgb = this.pages[pg].rgb;
      const { pixels, texels } = this.shown[pg];
      for (let k = 0; k < pixels.length; k++) {
        const o = 3 * pixels[k];
        const t = 3 * texels[k];
        rgb[o] = texelValues[t];
        rgb[o + 1] = texelValues[t + 1];
        rgb[o + 2] = texelValues[t + 2];
      }
    }
  }

  /**
   * Per probe, the change of the live layer's radiance SH since the baked
   * suns (live/src/probes.rs, `Live::probe_delta`): (4π / n) Σᵢ ΔL(patch
   * hit by ray i) Y(ωᵢ) over the probe's rays, ΔL the patches' outgoing
   * radiance now less at the baked suns, filled into the invalid probes
   * as the bake fills them; the baked radiance is the file's (the
   * patches' L at the baked suns, exact visibility). A Float32Array of 27
   * per probe (nine RGB coefficients, as `probes.bin`), or null for a file
   * without the probes' rays.
   */
  probeDelta() {
    const probes = this.data.probes;
    const q = this.header.probes;
    if (!probes || !q) return null;
    if (!this.probeBasis) {
      this.probeBasis = weightedBasis(q.rays);
      this.probeFill = fillPlan(q.grids, probes.valid);
    }
    const dl = new Float32Array(this.radiance.length);
    for (let i = 0; i < dl.length; i++) dl[i] = this.radiance[i] - probes.baked[i];
    const n = q.rays;
    const y = this.probeBasis;
    const out = new Float32Array(27 * q.count);
    const { valid, hits } = probes;
    // 27 accumulators in locals: typed-array writes per ray cost 3 × as much in V8.
    for (let p = 0; p < q.count; p++) {
      if (!valid[p]) continue;
      let r0 = 0, r1 = 0, r2 = 0, r3 = 0, r4 = 0, r5 = 0, r6 = 0, r7 = 0, r8 = 0;
      let g0 = 0, g1 = 0, g2 = 0, g3 = 0, g4 = 0, g5 = 0, g6 = 0, g7 = 0, g8 = 0;
      let b0 = 0, b1 = 0, b2 = 0, b3 = 0, b4 = 0, b5 = 0, b6 = 0, b7 = 0, b8 = 0;
      for (let i = 0, at = p * n; i < n; i++) {
        const hit = hits[at + i];
        if (hit === NONE) continue;
        const r = dl[3 * hit];
        const g = dl[3 * hit + 1];
        const b = dl[3 * hit + 2];
        if (r === 0 && g === 0 && b === 0) continue;
        const o = 9 * i;
        const y0 = y[o], y1 = y[o + 1], y2 = y[o + 2], y3 = y[o + 3], y4 = y[o + 4], y5 = y[o + 5], y6 = y[o + 6], y7 = y[o + 7], y8 = y[o + 8];
        r0 += r * y0; r1 += r * y1; r2 += r * y2; r3 += r * y3; r4 += r * y4; r5 += r * y5; r6 += r * y6; r7 += r * y7; r8 += r * y8;
        g0 += g * y0; g1 += g * y1; g2 += g * y2; g3 += g * y3; g4 += g * y4; g5 += g * y5; g6 += g * y6; g7 += g * y7; g8 += g * y8;
        b0 += b * y0; b1 += b * y1; b2 += b * y2; b3 += b * y3; b4 += b * y4; b5 += b * y5; b6 += b * y6; b7 += b * y7; b8 += b * y8;
      }
      out.set([r0, g0, b0, r1, g1, b1, r2, g2, b2, r3, g3, b3, r4, g4, b4, r5, g5, b5, r6, g6, b6, r7, g7, b7, r8, g8, b8], 27 * p);
    }
    for (const [p, from] of this.probeFill) {
      for (let c = 0; c < 27; c++) {
        let sum = 0;
        for (const j of from) sum += out[27 * j + c];
        out[27 * p + c] = sum / from.length;
      }
    }
    return out;
  }
}

/** Direction i of a spherical Fibonacci set of n (live/src/probes.rs `fibonacci`). */
export function fibonacci(i, n) {
  const golden = 0.618034;
  const z = 1 - (2 * i + 1) / n;
  const r = Math.sqrt(Math.max(1 - z * z, 0));
  const phi = 2 * Math.PI * ((i * golden) % 1);
  return [r * Math.cos(phi), r * Math.sin(phi), z];
}

/** The nine real SH basis functions at unit d, three.js's order and normalisation. */
export function shBasis([x, y, z]) {
  return [0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y)];
}

/** Per ray of an n-ray Fibonacci set, its basis × 4π / n: a Float32Array of 9 per ray. */
function weightedBasis(n) {
  const out = new Float32Array(9 * n);
  const w = (4 * Math.PI) / n;
  for (let i = 0; i < n; i++) shBasis(fibonacci(i, n)).forEach((v, k) => (out[9 * i + k] = v * w));
  return out;
}

/**
 * The invalid probes' fill (live/src/probes.rs `fill_plan`): ring by
 * ring, each unfilled probe with filled neighbours among its 26 takes
 * their mean. A list of [probe, [sources]] in the order to apply.
 */
export function fillPlan(grids, valid) {
  const plan = [];
  for (const { first, resolution: [rx, ry, rz] } of grids) {
    const n = rx * ry * rz;
    const filled = Array.from({ length: n }, (_, i) => valid[first + i] !== 0);
    const index = (x, y, z) => x + rx * (y + ry * z);
    for (;;) {
      const ring = [];
      for (let i = 0; i < n; i++) {
        if (filled[i]) continue;
        const x = i % rx;
        const y = Math.floor(i / rx) % ry;
        const z = Math.floor(i / (rx * ry));
        const from = [];
        for (let dz = -1; dz <= 1; dz++) {
          for (let dy = -1; dy <= 1; dy++) {
            for (let dx = -1; dx <= 1; dx++) {
              const [qx, qy, qz] = [x + dx, y + dy, z + dz];
              const inside = qx >= 0 && qx < rx && qy >= 0 && qy < ry && qz >= 0 && qz < rz;
              if ((dx || dy || dz) && inside && filled[index(qx, qy, qz)]) from.push(first + index(qx, qy, qz));
            }
          }
        }
        if (from.length) ring.push([first + i, from]);
      }
      if (!ring.length) break;
      for (const [i] of ring) filled[i - first] = true;
      plan.push(...ring);
    }
  }
  return plan;
}
