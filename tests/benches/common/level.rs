//! A generated game level for benchmarks and big-scene tests: a three-storey
//! atrium (36 m × 24 m × 13.5 m) with floor slabs around an open well, outer
//! walls, finely tessellated columns and arches around the well on every
//! storey (one column mesh and one arch mesh, placed by 72 nodes each), four
//! emissive wall panels and a sun (`KHR_lights_punctual` directional) that
//! shines through the open roof.
//!
//! The column and arch tessellation is chosen so the instanced triangle
//! count comes as close as it can to the requested one; the surface area
//! (hence the texel count of a bake) stays the same at every size. Pure
//! function of the request: the same count gives the same bytes.
//!
//! Shared by `tools/gen_level.rs` and the benchmarks (`tests/benches/`).
#![allow(dead_code)]

use glam::{Quat, Vec3};
use serde_json::{json, Value};

/// One triangle mesh (one glTF primitive).
#[derive(Clone, Debug, Default)]
pub struct MeshData {
    /// glTF mesh name.
    pub name: String,
    /// Vertex positions (local, metres).
    pub positions: Vec<Vec3>,
    /// Vertex normals (unit).
    pub normals: Vec<Vec3>,
    /// Triangles, counter-clockwise seen from the front.
    pub indices: Vec<u32>,
    /// Index into [`Level::materials`].
    pub material: usize,
}

impl MeshData {
    fn new(name: &str, material: usize) -> MeshData {
        MeshData {
            name: name.into(),
            material,
            ..Default::default()
        }
    }

    fn vertex(&mut self, p: Vec3, n: Vec3) -> u32 {
        self.positions.push(p);
        self.normals.push(n);
        self.positions.len() as u32 - 1
    }

    /// A triangle wound so that its front faces the way its vertex normals
    /// do; degenerate ones are left out.
    fn tri(&mut self, a: u32, b: u32, c: u32) {
        let p = |i: u32| self.positions[i as usize];
        let n = |i: u32| self.normals[i as usize];
        let cross = (p(b) - p(a)).cross(p(c) - p(a));
        if cross.length_squared() < 1e-12 {
            return;
        }
        if cross.dot(n(a) + n(b) + n(c)) >= 0.0 {
            self.indices.extend([a, b, c]);
        } else {
            self.indices.extend([a, c, b]);
        }
    }

    /// A flat quad (corners in order around it) facing `n`.
    fn quad(&mut self, corners: [Vec3; 4], n: Vec3) {
        let v = corners.map(|p| self.vertex(p, n));
        self.tri(v[0], v[1], v[2]);
        self.tri(v[0], v[2], v[3]);
    }

    /// An axis-aligned box; `faces` says which of −X, +X, −Y, +Y, −Z, +Z to
    /// make (faces against another solid are left out).
    fn cuboid(&mut self, min: Vec3, max: Vec3, faces: [bool; 6]) {
        let c = |x: bool, y: bool, z: bool| {
            Vec3::new(
                if x { max.x } else { min.x },
                if y { max.y } else { min.y },
                if z { max.z } else { min.z },
            )
        };
        let (f, t) = (false, true);
        let sides = [
            ([c(f, f, f), c(f, t, f), c(f, t, t), c(f, f, t)], -Vec3::X),
            ([c(t, f, f), c(t, t, f), c(t, t, t), c(t, f, t)], Vec3::X),
            ([c(f, f, f), c(t, f, f), c(t, f, t), c(f, f, t)], -Vec3::Y),
            ([c(f, t, f), c(t, t, f), c(t, t, t), c(f, t, t)], Vec3::Y),
            ([c(f, f, f), c(t, f, f), c(t, t, f), c(f, t, f)], -Vec3::Z),
            ([c(f, f, t), c(t, f, t), c(t, t, t), c(f, t, t)], Vec3::Z),
        ];
        for (k, (corners, n)) in sides.into_iter().enumerate() {
            if faces[k] {
                self.quad(corners, n);
            }
        }
    }

    /// Number of triangles.
    pub fn triangles(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A node placing a mesh.
#[derive(Clone, Debug)]
pub struct NodeData {
    /// Node name.
    pub name: String,
    /// Index into [`Level::meshes`].
    pub mesh: usize,
    /// Translation (metres).
    pub translation: Vec3,
    /// Rotation about +Y (radians).
    pub yaw: f32,
}

/// A Lambertian material, optionally emissive.
#[derive(Clone, Debug)]
pub struct MaterialData {
    /// Name.
    pub name: String,
    /// Linear albedo.
    pub albedo: [f32; 3],
    /// Emitted radiance (W·sr⁻¹·m⁻²).
    pub emission: [f32; 3],
}

/// The whole level.
#[derive(Clone, Debug)]
pub struct Level {
    /// Meshes.
    pub meshes: Vec<MeshData>,
    /// Nodes (every one a root).
    pub nodes: Vec<NodeData>,
    /// Materials.
    pub materials: Vec<MaterialData>,
    /// Direction the sunlight travels (unit).
    pub sun_direction: Vec3,
    /// Sun irradiance (W/m², glTF `intensity`).
    pub sun_intensity: f32,
    /// Column segments around (the tessellation chosen).
    pub column_segments: u32,
}

/// Storeys, their height and the slab thickness (metres).
const STOREYS: u32 = 3;
const STOREY: f32 = 4.5;
const SLAB: f32 = 0.3;
/// Half extents of the building (inner faces of the outer walls).
const HALF_X: f32 = 18.0;
const HALF_Z: f32 = 12.0;
const WALL: f32 = 0.3;
/// Column lines around the well, column spacing and radius.
const COL_X: f32 = 12.0;
const COL_Z: f32 = 6.0;
const SPACING: f32 = 3.0;
const RADIUS: f32 = 0.3;
/// The well (open on the upper floors and the roof) is this much inside the column lines.
const WELL_INSET: f32 = 0.4;
/// Arch: radius (half the clear span), lintel height above it, thickness.
const ARCH_R: f32 = (SPACING - 2.0 * RADIUS) / 2.0;
const LINTEL: f32 = 0.6;
const ARCH_T: f32 = 0.4;

/// Column: a cylinder of `seg` × `rings` quads on a square plinth, with a
/// square capital (slabs of stone the cylinder meets).
fn column(seg: u32, rings: u32, material: usize) -> MeshData {
    let h = STOREY - SLAB;
    let (plinth, capital) = (0.25, 0.25);
    let mut m = MeshData::new("column", material);
    let w = RADIUS + 0.1;
    m.cuboid(
        Vec3::new(-w, 0.0, -w),
        Vec3::new(w, plinth, w),
        [true, true, false, true, true, true],
    );
    m.cuboid(
        Vec3::new(-w, h - capital, -w),
        Vec3::new(w, h, w),
        [true, true, true, false, true, true],
    );
    let shaft = h - plinth - capital;
    let base = m.positions.len() as u32;
    for r in 0..=rings {
        let y = plinth + shaft * r as f32 / rings as f32;
        for s in 0..seg {
            let a = std::f32::consts::TAU * s as f32 / seg as f32;
            let n = Vec3::new(a.cos(), 0.0, a.sin());
            m.vertex(n * RADIUS + Vec3::Y * y, n);
        }
    }
    for r in 0..rings {
        for s in 0..seg {
            let i = |r: u32, s: u32| base + r * seg + s % seg;
            m.tri(i(r, s), i(r, s + 1), i(r + 1, s + 1));
            m.tri(i(r, s), i(r + 1, s + 1), i(r + 1, s));
        }
    }
    m
}

/// Arch between two columns, in the XY plane (spanning x ∈ [−R, R],
/// springing at y = 0, thickness along Z), with a lintel above up to the
/// slab: front and back faces between the semicircle and its bounding
/// square, the intrados, the lintel's faces and the ends.
fn arch(seg: u32, material: usize) -> MeshData {
    let (r, t) = (ARCH_R, ARCH_T / 2.0);
    let seg = seg.div_ceil(4).max(1) * 4; // corners of the square are samples
    let mut m = MeshData::new("arch", material);
    let arc = |k: u32| {
        let a = std::f32::consts::PI * k as f32 / seg as f32;
        Vec3::new(a.cos(), a.sin(), 0.0)
    };
    // The point of the square [−R, R] × [0, R] hit by the ray from the centre along `d`.
    let square = |d: Vec3| d * (r / d.x.abs().max(d.y));
    for side in [-1.0f32, 1.0] {
        let n = Vec3::Z * side;
        let z = Vec3::Z * (t * side);
        let base = m.positions.len() as u32;
        for k in 0..=seg {
            m.vertex(arc(k) * r + z, n);
            m.vertex(square(arc(k)) + z, n);
        }
        for k in 0..seg {
            let (a0, o0, a1, o1) = (
                base + 2 * k,
                base + 2 * k + 1,
                base + 2 * k + 2,
                base + 2 * k + 3,
            );
            m.tri(a0, a1, o1);
            m.tri(a0, o1, o0);
        }
    }
    // Intrados: faces the arch's centre.
    let base = m.positions.len() as u32;
    for k in 0..=seg {
        let d = arc(k);
        m.vertex(d * r - Vec3::Z * t, -d);
        m.vertex(d * r + Vec3::Z * t, -d);
    }
    for k in 0..seg {
        let (a, b, c, d) = (
            base + 2 * k,
            base + 2 * k + 1,
            base + 2 * k + 2,
            base + 2 * k + 3,
        );
        m.tri(a, c, d);
        m.tri(a, d, b);
    }
    // Ends against the columns, and the lintel (its top is against the slab).
    m.cuboid(
        Vec3::new(-r, 0.0, -t),
        Vec3::new(r, r, t),
        [true, true, false, false, false, false],
    );
    m.cuboid(
        Vec3::new(-r, r, -t),
        Vec3::new(r, r + LINTEL, t),
        [true, true, false, false, true, true],
    );
    m
}

/// A floor slab around the well (or the roof).
fn ring_slab(material: usize) -> MeshData {
    let mut m = MeshData::new("slab", material);
    let (wx, wz) = (COL_X - WELL_INSET, COL_Z - WELL_INSET);
    let y = Vec3::Y * SLAB;
    let v = |x: f32, z: f32| Vec3::new(x, 0.0, z);
    // North and south strips the full width, east and west between them.
    m.cuboid(
        v(-HALF_X, wz),
        v(HALF_X, HALF_Z) + y,
        [false, false, true, true, true, false],
    );
    m.cuboid(
        v(-HALF_X, -HALF_Z),
        v(HALF_X, -wz) + y,
        [false, false, true, true, false, true],
    );
    m.cuboid(
        v(-HALF_X, -wz),
        v(-wx, wz) + y,
        [false, true, true, true, false, false],
    );
    m.cuboid(
        v(wx, -wz),
        v(HALF_X, wz) + y,
        [true, false, true, true, false, false],
    );
    m
}

/// Outer walls, full height, both faces.
fn walls(material: usize) -> MeshData {
    let mut m = MeshData::new("walls", material);
    let h = STOREY * STOREYS as f32;
    let all = [true; 6];
    let (x, z, w) = (HALF_X, HALF_Z, WALL);
    m.cuboid(Vec3::new(-x - w, 0.0, z), Vec3::new(x + w, h, z + w), all);
    m.cuboid(Vec3::new(-x - w, 0.0, -z - w), Vec3::new(x + w, h, -z), all);
    // East and west walls run between the north and south ones.
    let ends = [true, true, false, true, false, false];
    m.cuboid(Vec3::new(x, 0.0, -z), Vec3::new(x + w, h, z), ends);
    m.cuboid(Vec3::new(-x - w, 0.0, -z), Vec3::new(-x, h, z), ends);
    m
}

/// The ground: one quad under the whole building.
fn ground(material: usize) -> MeshData {
    let mut m = MeshData::new("ground", material);
    let (x, z) = (HALF_X, HALF_Z);
    m.quad(
        [
            Vec3::new(-x, 0.0, -z),
            Vec3::new(x, 0.0, -z),
            Vec3::new(x, 0.0, z),
            Vec3::new(-x, 0.0, z),
        ],
        Vec3::Y,
    );
    m
}

/// Four lamps: thin emissive boxes on the inner faces of the walls.
fn panels(material: usize) -> MeshData {
    let mut m = MeshData::new("panels", material);
    let d = 0.05;
    let (y0, y1) = (1.6, 2.6);
    m.cuboid(
        Vec3::new(-1.5, y0, HALF_Z - d),
        Vec3::new(1.5, y1, HALF_Z),
        [true, true, true, true, true, false],
    );
    m.cuboid(
        Vec3::new(-1.5, y0, -HALF_Z),
        Vec3::new(1.5, y1, -HALF_Z + d),
        [true, true, true, true, false, true],
    );
    m.cuboid(
        Vec3::new(HALF_X - d, y0, -1.5),
        Vec3::new(HALF_X, y1, 1.5),
        [true, false, true, true, true, true],
    );
    m.cuboid(
        Vec3::new(-HALF_X, y0, -1.5),
        Vec3::new(-HALF_X + d, y1, 1.5),
        [false, true, true, true, true, true],
    );
    m
}

/// Column and arch placements: (x, z, yaw) on the column lines.
fn column_spots() -> Vec<(f32, f32)> {
    let mut v = Vec::new();
    let nx = (2.0 * COL_X / SPACING).round() as i32;
    let nz = (2.0 * COL_Z / SPACING).round() as i32;
    for z in [-COL_Z, COL_Z] {
        for i in 0..=nx {
            v.push((-COL_X + SPACING * i as f32, z));
        }
    }
    for x in [-COL_X, COL_X] {
        for i in 1..nz {
            v.push((x, -COL_Z + SPACING * i as f32));
        }
    }
    v
}

fn arch_spots() -> Vec<(f32, f32, f32)> {
    let mut v = Vec::new();
    let nx = (2.0 * COL_X / SPACING).round() as i32;
    let nz = (2.0 * COL_Z / SPACING).round() as i32;
    for z in [-COL_Z, COL_Z] {
        for i in 0..nx {
            v.push((-COL_X + SPACING * (i as f32 + 0.5), z, 0.0));
        }
    }
    for x in [-COL_X, COL_X] {
        for i in 0..nz {
            v.push((
                x,
                -COL_Z + SPACING * (i as f32 + 0.5),
                std::f32::consts::FRAC_PI_2,
            ));
        }
    }
    v
}

/// Rings along the shaft for `seg` segments around: near-square quads.
fn rings_for(seg: u32) -> u32 {
    let shaft = STOREY - SLAB - 0.5;
    ((seg as f32 * shaft / (std::f32::consts::TAU * RADIUS)).round() as u32).max(1)
}

/// The level with the column tessellation that brings the instanced
/// triangle count closest to `target_triangles`.
pub fn generate(target_triangles: u64) -> Level {
    // The count grows with seg²: scan up to the first level at or above the target.
    let mut best = build(4);
    for seg in 5..4096 {
        let next = build(seg);
        let count = next.triangle_count();
        if count.abs_diff(target_triangles) <= best.triangle_count().abs_diff(target_triangles) {
            best = next;
        }
        if count >= target_triangles {
            break;
        }
    }
    best
}

fn build(seg: u32) -> Level {
    let materials = vec![
        MaterialData {
            name: "floor".into(),
            albedo: [0.55, 0.5, 0.45],
            emission: [0.0; 3],
        },
        MaterialData {
            name: "plaster".into(),
            albedo: [0.8, 0.78, 0.72],
            emission: [0.0; 3],
        },
        MaterialData {
            name: "stone".into(),
            albedo: [0.7, 0.65, 0.55],
            emission: [0.0; 3],
        },
        MaterialData {
            name: "lamp".into(),
            albedo: [0.8, 0.8, 0.8],
            emission: [20.0, 16.0, 12.0],
        },
    ];
    let meshes = vec![
        ground(0),
        ring_slab(0),
        walls(1),
        panels(3),
        column(seg, rings_for(seg), 2),
        arch(seg, 2),
    ];
    let mut nodes = vec![
        node("ground", 0, Vec3::ZERO, 0.0),
        node("walls", 2, Vec3::ZERO, 0.0),
        node("lamps", 3, Vec3::ZERO, 0.0),
    ];
    for s in 1..=STOREYS {
        let name = if s == STOREYS {
            "roof".to_string()
        } else {
            format!("floor_{s}")
        };
        nodes.push(node(&name, 1, Vec3::Y * (STOREY * s as f32 - SLAB), 0.0));
    }
    for s in 0..STOREYS {
        let y = STOREY * s as f32;
        for (k, (x, z)) in column_spots().into_iter().enumerate() {
            nodes.push(node(&format!("column_{s}_{k}"), 4, Vec3::new(x, y, z), 0.0));
        }
        let spring = y + STOREY - SLAB - LINTEL - ARCH_R;
        for (k, (x, z, yaw)) in arch_spots().into_iter().enumerate() {
            nodes.push(node(
                &format!("arch_{s}_{k}"),
                5,
                Vec3::new(x, spring, z),
                yaw,
            ));
        }
    }
    Level {
        meshes,
        nodes,
        materials,
        sun_direction: Vec3::new(0.3, -1.0, 0.2).normalize(),
        sun_intensity: 8.0,
        column_segments: seg,
    }
}

fn node(name: &str, mesh: usize, translation: Vec3, yaw: f32) -> NodeData {
    NodeData {
        name: name.into(),
        mesh,
        translation,
        yaw,
    }
}

impl Level {
    /// Triangles after instancing.
    pub fn triangle_count(&self) -> u64 {
        self.nodes
            .iter()
            .map(|n| self.meshes[n.mesh].triangles() as u64)
            .sum()
    }

    /// The level as a glTF document and its binary buffer (for
    /// `radbake::output::baked::glb`).
    pub fn to_gltf(&self) -> (Value, Vec<u8>) {
        let mut bin: Vec<u8> = Vec::new();
        let mut views = Vec::new();
        let mut accessors = Vec::new();
        let mut view = |bin: &mut Vec<u8>, bytes: &[u8], target: u32| {
            let offset = bin.len();
            bin.extend_from_slice(bytes);
            while bin.len() % 4 != 0 {
                bin.push(0);
            }
            views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len(), "target": target}));
            views.len() - 1
        };
        let mut meshes = Vec::new();
        for m in &self.meshes {
            let vec3 = |v: &[Vec3]| -> Vec<u8> {
                v.iter()
                    .flat_map(|p| p.to_array())
                    .flat_map(f32::to_le_bytes)
                    .collect()
            };
            let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
            for p in &m.positions {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            let pv = view(&mut bin, &vec3(&m.positions), 34962);
            let nv = view(&mut bin, &vec3(&m.normals), 34962);
            let idx: Vec<u8> = m.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
            let iv = view(&mut bin, &idx, 34963);
            let n = m.positions.len();
            accessors.push(json!({"bufferView": pv, "componentType": 5126, "count": n, "type": "VEC3", "min": lo.to_array(), "max": hi.to_array()}));
            accessors
                .push(json!({"bufferView": nv, "componentType": 5126, "count": n, "type": "VEC3"}));
            accessors.push(json!({"bufferView": iv, "componentType": 5125, "count": m.indices.len(), "type": "SCALAR"}));
            let a = accessors.len();
            meshes.push(json!({
                "name": m.name,
                "primitives": [{"attributes": {"POSITION": a - 3, "NORMAL": a - 2}, "indices": a - 1, "material": m.material}],
            }));
        }
        let materials: Vec<Value> = self
            .materials
            .iter()
            .map(|m| {
                let a = m.albedo;
                let mut v = json!({
                    "name": m.name,
                    "pbrMetallicRoughness": {"baseColorFactor": [a[0], a[1], a[2], 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
                });
                let peak = m.emission.iter().cloned().fold(0.0f32, f32::max);
                if peak > 0.0 {
                    v["emissiveFactor"] = json!(m.emission.map(|e| e / peak));
                    v["extensions"] =
                        json!({"KHR_materials_emissive_strength": {"emissiveStrength": peak}});
                }
                v
            })
            .collect();
        let mut nodes: Vec<Value> = self
            .nodes
            .iter()
            .map(|n| {
                let mut v = json!({"name": n.name, "mesh": n.mesh});
                if n.translation != Vec3::ZERO {
                    v["translation"] = json!(n.translation.to_array());
                }
                if n.yaw != 0.0 {
                    v["rotation"] = json!(Quat::from_rotation_y(n.yaw).to_array());
                }
                v
            })
            .collect();
        // The sun: a directional light shines along its node's −Z.
        let sun = Quat::from_rotation_arc(-Vec3::Z, self.sun_direction);
        nodes.push(json!({"name": "sun", "rotation": sun.to_array(), "extensions": {"KHR_lights_punctual": {"light": 0}}}));
        // A camera on the ground floor looking across the well.
        let eye = Vec3::new(-16.0, 1.7, -10.0);
        let forward = (Vec3::new(0.0, 4.0, 0.0) - eye).normalize();
        let right = forward.cross(Vec3::Y).normalize();
        let rot = Quat::from_mat3(&glam::Mat3::from_cols(
            right,
            right.cross(forward),
            -forward,
        ));
        nodes.push(json!({"name": "camera", "camera": 0, "translation": eye.to_array(), "rotation": rot.to_array()}));
        let roots: Vec<usize> = (0..nodes.len()).collect();
        let doc = json!({
            "asset": {"version": "2.0", "generator": "radbake gen_level"},
            "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
            "extensions": {"KHR_lights_punctual": {"lights": [
                {"name": "sun", "type": "directional", "color": [1.0, 0.95, 0.85], "intensity": self.sun_intensity}
            ]}},
            "cameras": [{"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.05, "aspectRatio": 1.7777778}}],
            "scene": 0,
            "scenes": [{"nodes": roots}],
            "nodes": nodes,
            "meshes": meshes,
            "materials": materials,
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{"byteLength": bin.len()}],
        });
        (doc, bin)
    }
}
