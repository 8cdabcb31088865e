//! Shared set-up of the benchmarks (and of `tools/dump_rays.rs`): the
//! generated level, world triangles without a lightmap atlas, seeded
//! incoherent rays, and the Cornell box baked once.
#![allow(dead_code)]

pub mod level;

use glam::{Vec2, Vec3};
use radbake::layout::geometry::Geometry;
use radbake::scene::Scene;
use radbake::util::sampling::{cosine_hemisphere, offset_ray_origin, to_world, Stream};
use std::path::{Path, PathBuf};

/// The seed of every benchmark's random sequence.
pub const SEED: u64 = 0xbe4c;

/// The generated level of about `triangles` triangles, written as a `.glb`
/// and read back through radbake's importer.
pub fn level_scene(triangles: u64) -> Scene {
    let level = level::generate(triangles);
    let (doc, bin) = level.to_gltf();
    let path = std::env::temp_dir().join(format!(
        "radbake-bench-level-{}-{triangles}.glb",
        std::process::id()
    ));
    std::fs::write(&path, radbake::output::baked::glb(&doc, &bin)).expect("write the level");
    let scene = radbake::scene::load(&path, &Default::default()).expect("the level loads");
    let _ = std::fs::remove_file(&path);
    scene
}

/// A shipped reference scene (`scenes/<name>`).
pub fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

/// The Cornell box, imported.
pub fn cornell() -> Scene {
    radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default())
        .expect("scenes/cornell_box.gltf loads")
}

/// Every instance's triangles in world space, as [`Geometry`] without
/// lightmap coordinates (enough for [`radbake::raycast::RayCaster`]).
pub fn world_geometry(scene: &Scene) -> Geometry {
    let mut g = Geometry::default();
    for (i, inst) in scene.instances.iter().enumerate() {
        let mesh = &scene.meshes[inst.mesh as usize];
        let flip = inst.mirrors();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let mut p = tri.map(|k| {
                inst.world_from_local
                    .transform_point3(mesh.positions[k as usize])
            });
            if flip {
                p.swap(1, 2);
            }
            let cross = (p[1] - p[0]).cross(p[2] - p[0]);
            let n = cross.normalize_or(Vec3::Y);
            g.instance.push(i as u32);
            g.p_ws.push(p);
            g.n_ws.push([n; 3]);
            g.ng_ws.push(n);
            g.area.push(0.5 * cross.length());
            g.uv0.push([Vec2::ZERO; 3]);
            g.uv_lm.push([Vec2::ZERO; 3]);
            g.page.push(0);
            g.chart.push(0);
            g.material.push(mesh.triangle_material[t]);
        }
    }
    g
}

/// A set of rays: origin, unit direction, largest distance.
#[derive(Clone, Debug, Default)]
pub struct Rays {
    /// Origins (already offset off their surface).
    pub origin: Vec<Vec3>,
    /// Unit directions.
    pub dir: Vec<Vec3>,
    /// Largest hit distance (∞ for closest-hit rays).
    pub tmax: Vec<f32>,
}

impl Rays {
    /// Number of rays.
    pub fn len(&self) -> usize {
        self.origin.len()
    }
}

/// Picks triangles by area from one uniform number (binary search in the CDF).
struct AreaSampler {
    cdf: Vec<f64>,
}

impl AreaSampler {
    fn new(g: &Geometry) -> AreaSampler {
        let mut total = 0.0;
        let cdf = g
            .area
            .iter()
            .map(|a| {
                total += *a as f64;
                total
            })
            .collect();
        AreaSampler { cdf }
    }

    /// A uniformly distributed surface point and its geometric normal.
    fn point(&self, g: &Geometry, s: &mut Stream) -> (Vec3, Vec3) {
        let total = *self.cdf.last().expect("some triangles");
        let x = s.next_f32() as f64 * total;
        let t = self
            .cdf
            .partition_point(|c| *c <= x)
            .min(self.cdf.len() - 1);
        let (mut u, mut v) = (s.next_f32(), s.next_f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        (g.point(t as u32, u, v), g.ng_ws[t])
    }
}

/// `n` incoherent closest-hit rays, as a bake casts them: from uniformly
/// distributed surface points, in cosine-weighted directions about the
/// front normal, unbounded.
pub fn surface_rays(g: &Geometry, n: usize, seed: u64) -> Rays {
    let sampler = AreaSampler::new(g);
    let mut rays = Rays::default();
    for k in 0..n {
        let mut s = Stream::new(seed, 100, k as u64);
        let (p, ng) = sampler.point(g, &mut s);
        let dir = to_world(cosine_hemisphere(s.next_vec2()), ng);
        rays.origin.push(offset_ray_origin(p, ng));
        rays.dir.push(dir);
        rays.tmax.push(f32::INFINITY);
    }
    rays
}

/// `n` incoherent occlusion (shadow) rays: segments between two uniformly
/// distributed surface points, the first in front of the second's surface
/// and vice versa (pairs facing away are redrawn).
pub fn shadow_rays(g: &Geometry, n: usize, seed: u64) -> Rays {
    let sampler = AreaSampler::new(g);
    let mut rays = Rays::default();
    for k in 0..n {
        let mut s = Stream::new(seed, 101, k as u64);
        loop {
            let (p, np) = sampler.point(g, &mut s);
            let (q, nq) = sampler.point(g, &mut s);
            let d = q - p;
            let len = d.length();
            if len < 1e-3 || np.dot(d) <= 0.0 || nq.dot(d) >= 0.0 {
                continue;
            }
            let (o, e) = (offset_ray_origin(p, np), offset_ray_origin(q, nq));
            let dir = (e - o) / (e - o).length();
            rays.origin.push(o);
            rays.dir.push(dir);
            rays.tmax.push((e - o).length());
            break;
        }
    }
    rays
}

/// Criterion settings of every benchmark here: short runs (10 samples, 1 s
/// warm-up, 3 s measurement), since the machines are small and shared.
pub fn criterion() -> criterion::Criterion {
    criterion::Criterion::default()
        .sample_size(10)
        .warm_up_time(std::time::Duration::from_secs(1))
        .measurement_time(std::time::Duration::from_secs(3))
}

/// The Cornell box baked once with the medium preset: the products every
/// stage benchmark starts from.
pub fn cornell_bake(scene: &Scene) -> radbake::Bake<'_> {
    radbake::bake(scene, &radbake::BakeConfig::medium(), &radbake::Silent)
        .expect("the Cornell box bakes")
}

/// The emission entering the solve per patch (emitters sampled as direct
/// light are left out, as `radbake::bake` does).
pub fn solve_emission(bake: &radbake::Bake) -> Vec<Vec3> {
    let sampled =
        radbake::light::lights::sampled_materials(bake.scene, &bake.geometry, bake.config.emitters);
    (0..bake.patches.len())
        .map(|i| {
            let t = bake.patches.texels_of(i)[0] as usize;
            let m = bake.geometry.material[bake.texels.triangle[t] as usize] as usize;
            if sampled[m] {
                Vec3::ZERO
            } else {
                bake.patches.emission[i]
            }
        })
        .collect()
}
