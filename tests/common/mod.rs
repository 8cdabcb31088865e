//! Test helpers: the shipped reference scenes, and a tiny glTF writer for
//! scenes made in code (analytic cases and hostile inputs).
#![allow(dead_code)]

use base64::Engine as _;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// A reference scene shipped in `scenes/` (copied from `../shared/scenes`).
pub fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

/// `scenes/expected.json`.
pub fn expected() -> Value {
    let text = std::fs::read_to_string(scene_path("expected.json")).expect("scenes/expected.json");
    serde_json::from_str(&text).expect("expected.json parses")
}

/// A fresh, empty temporary folder for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("radbake-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Builds a glTF 2.0 JSON document with one embedded (data URI) buffer.
#[derive(Default)]
pub struct GltfBuilder {
    pub buffer: Vec<u8>,
    pub views: Vec<Value>,
    pub accessors: Vec<Value>,
    pub meshes: Vec<Value>,
    pub nodes: Vec<Value>,
    pub materials: Vec<Value>,
}

/// Little-endian bytes of float vectors, as an accessor's buffer view holds them.
fn le_bytes<const N: usize>(data: &[[f32; N]]) -> Vec<u8> {
    data.iter()
        .flatten()
        .flat_map(|f| f.to_le_bytes())
        .collect()
}

impl GltfBuilder {
    fn push_view(&mut self, bytes: &[u8], target: u32) -> usize {
        while self.buffer.len() % 4 != 0 {
            self.buffer.push(0);
        }
        let offset = self.buffer.len();
        self.buffer.extend_from_slice(bytes);
        self.views.push(
            json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len(), "target": target}),
        );
        self.views.len() - 1
    }

    /// A VEC3 float accessor (with min/max, as POSITION requires).
    pub fn vec3(&mut self, data: &[[f32; 3]]) -> usize {
        let bytes = le_bytes(data);
        let view = self.push_view(&bytes, 34962);
        let mut min = [f32::INFINITY; 3];
        let mut max = [f32::NEG_INFINITY; 3];
        for p in data {
            for c in 0..3 {
                min[c] = min[c].min(p[c]);
                max[c] = max[c].max(p[c]);
            }
        }
        let (min, max): (Vec<Value>, Vec<Value>) = if data.iter().flatten().all(|f| f.is_finite()) {
            (
                min.iter().map(|&v| json!(v)).collect(),
                max.iter().map(|&v| json!(v)).collect(),
            )
        } else {
            (vec![json!(0.0); 3], vec![json!(0.0); 3])
        };
        self.accessors.push(json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": "VEC3", "min": min, "max": max}));
        self.accessors.len() - 1
    }

    /// A VEC2 float accessor (texture coordinates).
    pub fn vec2(&mut self, data: &[[f32; 2]]) -> usize {
        let bytes = le_bytes(data);
        let view = self.push_view(&bytes, 34962);
        self.accessors.push(
            json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": "VEC2"}),
        );
        self.accessors.len() - 1
    }

    /// A SCALAR float accessor with min/max (animation inputs).
    pub fn scalars(&mut self, data: &[f32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.push_view(&bytes, 0);
        self.views[view].as_object_mut().unwrap().remove("target");
        let min = data.iter().cloned().fold(f32::INFINITY, f32::min);
        let max = data.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
        self.accessors.push(json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": "SCALAR", "min": [min], "max": [max]}));
        self.accessors.len() - 1
    }

    /// A SCALAR u32 index accessor.
    pub fn indices(&mut self, idx: &[u32]) -> usize {
        let bytes: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.push_view(&bytes, 34963);
        self.accessors.push(json!({"bufferView": view, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }

    /// A Lambertian material (albedo, emitted radiance).
    pub fn material(&mut self, albedo: [f32; 3], emission: [f32; 3]) -> usize {
        let peak = emission.iter().cloned().fold(0.0f32, f32::max);
        let mut m = json!({
            "pbrMetallicRoughness": {"baseColorFactor": [albedo[0], albedo[1], albedo[2], 1.0], "metallicFactor": 0.0},
        });
        if peak > 0.0 {
            let factor: Vec<f32> = if peak > 1.0 {
                emission.iter().map(|e| e / peak).collect()
            } else {
                emission.to_vec()
            };
            m["emissiveFactor"] = json!(factor);
            if peak > 1.0 {
                m["extensions"] =
                    json!({"KHR_materials_emissive_strength": {"emissiveStrength": peak}});
            }
        }
        self.materials.push(m);
        self.materials.len() - 1
    }

    /// A one-primitive mesh (no normals: flat normals are computed).
    pub fn mesh(
        &mut self,
        positions: &[[f32; 3]],
        indices: &[u32],
        material: Option<usize>,
    ) -> usize {
        let pos = self.vec3(positions);
        let idx = self.indices(indices);
        let mut prim = json!({"attributes": {"POSITION": pos}, "indices": idx});
        if let Some(m) = material {
            prim["material"] = json!(m);
        }
        self.meshes.push(json!({"primitives": [prim]}));
        self.meshes.len() - 1
    }

    /// A node placing `mesh`.
    pub fn node(&mut self, name: &str, mesh: usize) -> usize {
        self.nodes.push(json!({"name": name, "mesh": mesh}));
        self.nodes.len() - 1
    }

    /// The document (every node is a root of scene 0).
    pub fn json(&self) -> Value {
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&self.buffer)
        );
        let mut extensions_used = Vec::new();
        if self.materials.iter().any(|m| m.get("extensions").is_some()) {
            extensions_used.push("KHR_materials_emissive_strength");
        }
        json!({
            "asset": {"version": "2.0", "generator": "radbake tests"},
            "extensionsUsed": extensions_used,
            "scene": 0,
            "scenes": [{"nodes": (0..self.nodes.len()).collect::<Vec<_>>()}],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [{"byteLength": self.buffer.len(), "uri": uri}],
        })
    }

    /// Writes the document to `path`.
    pub fn write(&self, path: &Path) {
        std::fs::write(path, serde_json::to_vec_pretty(&self.json()).unwrap()).unwrap();
    }
}

/// A rectangle spanned from `origin` by edges `u` and `v`, facing `u × v`.
pub fn quad(origin: [f32; 3], u: [f32; 3], v: [f32; 3]) -> (Vec<[f32; 3]>, Vec<u32>) {
    let p = |a: f32, b: f32| [0, 1, 2].map(|c| origin[c] + a * u[c] + b * v[c]);
    (
        vec![p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)],
        vec![0, 1, 2, 0, 2, 3],
    )
}

/// A disk of radius `r` at height `y`, facing ±Y (`up`), as a fan of `n` triangles.
pub fn disk(r: f32, y: f32, up: bool, n: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut p = vec![[0.0, y, 0.0]];
    for k in 0..n {
        let a = k as f32 / n as f32 * std::f32::consts::TAU;
        p.push([r * a.cos(), y, -r * a.sin()]);
    }
    let mut idx = Vec::new();
    for k in 0..n {
        let (a, b) = (1 + k, 1 + (k + 1) % n);
        if up {
            idx.extend([0, a, b]);
        } else {
            idx.extend([0, b, a]);
        }
    }
    (p, idx)
}

/// A UV sphere of radius `r` facing outward (or inward).
pub fn sphere(r: f32, rings: u32, segments: u32, inward: bool) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut p = Vec::new();
    for i in 0..=rings {
        let th = i as f32 / rings as f32 * std::f32::consts::PI;
        for j in 0..=segments {
            let ph = j as f32 / segments as f32 * std::f32::consts::TAU;
            p.push([
                r * th.sin() * ph.cos(),
                r * th.cos(),
                -r * th.sin() * ph.sin(),
            ]);
        }
    }
    let w = segments + 1;
    let mut idx = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (
                i * w + j,
                i * w + j + 1,
                (i + 1) * w + j,
                (i + 1) * w + j + 1,
            );
            for t in [[a, c, b], [b, c, d]] {
                // Orient by the centroid: outward unless `inward`.
                let v = t.map(|k| p[k as usize]);
                let e1 = [0, 1, 2].map(|c| v[1][c] - v[0][c]);
                let e2 = [0, 1, 2].map(|c| v[2][c] - v[0][c]);
                let n = [
                    e1[1] * e2[2] - e1[2] * e2[1],
                    e1[2] * e2[0] - e1[0] * e2[2],
                    e1[0] * e2[1] - e1[1] * e2[0],
                ];
                let out: f32 = (0..3).map(|c| n[c] * (v[0][c] + v[1][c] + v[2][c])).sum();
                if (out > 0.0) != inward {
                    idx.extend(t);
                } else {
                    idx.extend([t[0], t[2], t[1]]);
                }
            }
        }
    }
    (p, idx)
}

/// Rotation of a node that turns its −Z (a light's direction) straight down.
#[allow(dead_code)]
pub const POINT_DOWN: [f32; 4] = [
    -std::f32::consts::FRAC_1_SQRT_2,
    0.0,
    0.0,
    std::f32::consts::FRAC_1_SQRT_2,
];

/// Adds a `KHR_lights_punctual` directional light of `intensity` (lux)
/// shining straight down, as a root node of scene 0.
#[allow(dead_code)]
pub fn add_vertical_sun(doc: &mut Value, intensity: f32) {
    doc["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    doc["extensions"] = json!({"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": intensity}]}});
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(json!({"name": "sun", "rotation": POINT_DOWN, "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    let sun = nodes.len() - 1;
    doc["scenes"][0]["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!(sun));
}

/// Appends `data` to `doc` as a VEC2 float accessor in a data-URI buffer of
/// its own; returns the accessor's index.
#[allow(dead_code)]
pub fn append_vec2_accessor(doc: &mut Value, data: &[[f32; 2]]) -> usize {
    let bytes: Vec<u8> = data
        .iter()
        .flatten()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bytes)
    );
    let buffer = doc["buffers"].as_array().unwrap().len();
    doc["buffers"]
        .as_array_mut()
        .unwrap()
        .push(json!({"byteLength": bytes.len(), "uri": uri}));
    let view = doc["bufferViews"].as_array().unwrap().len();
    doc["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({"buffer": buffer, "byteLength": bytes.len()}));
    let accessors = doc["accessors"].as_array_mut().unwrap();
    accessors.push(
        json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": "VEC2"}),
    );
    accessors.len() - 1
}

/// The sunlit ground of the probe and light-mode tests: half size `A`,
/// albedo `RHO`, sky `SKY`, sun `SUN` (W/m²), probe height `H`.
pub mod ground {
    pub const A: f32 = 10.0;
    pub const RHO: f32 = 0.5;
    pub const SKY: f32 = 0.8;
    pub const SUN: f32 = 3.0;
    pub const H: f32 = 2.0;
}

/// A ground square (albedo `ground::RHO`, half size `ground::A`) with one
/// probe (a `probe_volume` node of resolution 1) at height `ground::H` over
/// its centre, and with `sun` a directional light of `ground::SUN` W/m²
/// shining along −`to_sun` whose node carries `extras` (if any); written
/// to a fresh folder `name`.
pub fn sunlit_ground(name: &str, to_sun: glam::Vec3, sun: bool, extras: Option<Value>) -> PathBuf {
    use ground::{A, H, RHO, SUN};
    let mut b = GltfBuilder::default();
    let grey = b.material([RHO; 3], [0.0; 3]);
    let (p, i) = quad([-A, 0.0, -A], [0.0, 0.0, 2.0 * A], [2.0 * A, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("ground", m);
    let mut doc = b.json();
    let nodes = doc["nodes"].as_array_mut().unwrap();
    if sun {
        // A directional light shines along its node's −Z.
        let rot = glam::Quat::from_rotation_arc(glam::Vec3::NEG_Z, -to_sun);
        let mut node = json!({"name": "sun", "rotation": rot.to_array(),
            "extensions": {"KHR_lights_punctual": {"light": 0}}});
        if let Some(e) = extras {
            node["extras"] = e;
        }
        nodes.push(node);
    }
    nodes.push(json!({
        "name": "probe_box", "translation": [0.0, H, 0.0], "scale": [0.1, 0.1, 0.1],
        "extras": {"radbake": {"probe_volume": {"spacing": 1.0}}}
    }));
    let n = nodes.len();
    doc["scenes"][0]["nodes"] = json!((0..n).collect::<Vec<_>>());
    if sun {
        doc["extensionsUsed"] = json!(["KHR_lights_punctual"]);
        doc["extensions"] =
            json!({"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": SUN}]}});
    }
    let path = temp_dir(name).join("ground.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

pub fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Mean linear RGB of the 3 × 3 pixels at the image centre.
pub fn centre_linear(img: &image::RgbaImage) -> glam::Vec3 {
    let (w, h) = img.dimensions();
    let mut sum = glam::Vec3::ZERO;
    for y in h / 2 - 1..=h / 2 + 1 {
        for x in w / 2 - 1..=w / 2 + 1 {
            let p = img.get_pixel(x, y);
            sum += glam::Vec3::new(
                srgb_to_linear(p[0]),
                srgb_to_linear(p[1]),
                srgb_to_linear(p[2]),
            );
        }
    }
    sum / 9.0
}

// ---- A plate's edge under a light with a size (penumbra tests) ----

/// Plate height, sun irradiance (W/m²), texel density.
pub const H: f32 = 20.0;
pub const SUN: f32 = 2.0;
pub const DENSITY: f32 = 50.0;

/// A black 4 × 4 m ground at y = 0 and a black plate at height `H` over
/// x < 0 (edge along z at x = 0), under a sun straight down whose node
/// has `extras`.
pub fn edge_scene(name: &str, extras: Option<Value>) -> PathBuf {
    let mut b = GltfBuilder::default();
    let black = b.material([0.0; 3], [0.0; 3]);
    let (p, i) = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("ground", m);
    let (p, i) = quad([-2.5, H, -2.5], [0.0, 0.0, 5.0], [2.5, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("plate", m);
    let mut doc = b.json();
    add_vertical_sun(&mut doc, SUN);
    if let Some(e) = extras {
        let nodes = doc["nodes"].as_array_mut().unwrap();
        let sun = nodes.len() - 1;
        nodes[sun]["extras"] = e;
    }
    let path = temp_dir(name).join("edge.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

/// Fraction of the unit disk with coordinate below `a` (clamped).
pub fn disk_below(a: f64) -> f64 {
    let a = a.clamp(-1.0, 1.0);
    (a * (1.0 - a * a).sqrt() + a.asin() + std::f64::consts::PI / 2.0) / std::f64::consts::PI
}

/// Checks the penumbra on the ground below the plate's edge: per column
/// of ground texels (the mean over the 150 texels along the edge, so the
/// per-texel sampling noise averages out), the visible fraction
/// `fraction(texel)` is the analytic visible fraction F(x / r)
/// averaged over the texel's width within 0.03, and the 10–90 % width of
/// the penumbra is within 10 % of the analytic one. Returns the two widths.
pub fn check_penumbra(bake: &radbake::Bake, fraction: impl Fn(usize) -> f64, r: f64) -> (f64, f64) {
    let tx = &bake.texels;
    let width = 1.0 / DENSITY as f64;
    let mut cols: std::collections::BTreeMap<i64, (f64, f64, u32)> = Default::default();
    for t in 0..tx.len() {
        let p = tx.p_ws[t];
        if tx.instance[t] != 0 || p.z.abs() > 1.5 || (p.x as f64).abs() > 2.5 * r {
            continue;
        }
        if (tx.area[t] as f64) < 0.99 * width * width {
            continue; // a partly covered texel at the ground's edge
        }
        let key = (p.x as f64 / width).floor() as i64;
        let c = cols.entry(key).or_insert((0.0, 0.0, 0));
        c.0 += fraction(t);
        c.1 += p.x as f64;
        c.2 += 1;
    }
    assert!(cols.len() >= 8, "{} columns", cols.len());
    let mut worst = 0.0f64;
    let mut profile = Vec::new();
    for (sum, xs, n) in cols.values() {
        let x = xs / *n as f64;
        let got = sum / *n as f64;
        // F averaged over the texel's width.
        let k = 64;
        let want: f64 = (0..k)
            .map(|j| disk_below((x + width * ((j as f64 + 0.5) / k as f64 - 0.5)) / r))
            .sum::<f64>()
            / k as f64;
        eprintln!("x {x:+.4}: {got:.4} (analytic {want:.4}, {n} texels)");
        worst = worst.max((got - want).abs());
        profile.push((x, got));
    }
    assert!(worst < 0.03, "worst column {worst}");
    // The 10–90 % width, by linear interpolation of the column profile.
    let cross = |level: f64| {
        profile
            .windows(2)
            .find(|w| w[0].1 < level && w[1].1 >= level)
            .map(|w| w[0].0 + (level - w[0].1) / (w[1].1 - w[0].1) * (w[1].0 - w[0].0))
            .expect("the profile crosses the level")
    };
    let measured = cross(0.9) - cross(0.1);
    let solve = |level: f64| {
        let (mut lo, mut hi) = (-1.0, 1.0);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if disk_below(mid) < level {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo * r
    };
    let analytic = solve(0.9) - solve(0.1);
    eprintln!("10–90 % width: {measured:.4} m, analytic {analytic:.4} m (r = {r:.4} m)");
    assert!((measured / analytic - 1.0).abs() < 0.10);
    (measured, analytic)
}

// ---- Running the binary and reading its files ----

/// Runs `radbake` with `args`; panics with its stderr where it fails.
pub fn run_ok<I, S>(args: I) -> std::process::Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(args)
        .output()
        .expect("radbake runs");
    assert!(
        out.status.success(),
        "radbake failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The JSON chunk of a `.glb` file.
pub fn glb_json(path: &Path) -> Value {
    let glb = std::fs::read(path).unwrap();
    let len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&glb[20..20 + len]).unwrap()
}

/// A one-level, Zstandard-supercompressed KTX2 file: its header and its
/// level's bytes.
pub fn ktx2_level(path: &Path) -> (ktx2::Header, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let reader = ktx2::Reader::new(&bytes[..]).unwrap();
    let level = reader.levels().next().unwrap();
    let data = zstd::bulk::decompress(level.data, 1 << 30).unwrap();
    (reader.header(), data)
}

/// `f` run on a rayon pool of `threads` threads (for determinism tests).
#[allow(dead_code)]
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
        .install(f)
}
