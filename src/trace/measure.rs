//! An irradiance meter that shares no code with the lightmap pipeline's
//! atlas, texels, validity test or hole filling: the oracle that the bake's
//! per-instance figures (`report.json`'s `mean`) are tested against.
//!
//! For each node it samples points uniformly by area over the node's world
//! triangles (a triangle picked in proportion to its area, then a uniform
//! point on it; Turk 1990), takes the interpolated `NORMAL` there (or the
//! facet's own normal with `--normal geometric`, the texels' quantity: see
//! docs/lighting.md), and
//! path-traces the incident irradiance / π along cosine-distributed
//! directions with every bounce ([`Tracer::incident`]: next-event estimation
//! of the lights with MIS, Russian roulette). The reading is the sample mean
//! and its standard error, σ / √N per channel: an unbiased estimate of the
//! area-weighted mean irradiance / π over the node, buried parts included
//! at what they receive (nothing, for a point inside a wall). Like the
//! lightmap, it leaves out the direct light of `indirect` and
//! `shadowmask` lights ([`crate::scene::LightMode`]), and counts their
//! bounces.
//!
//! Deterministic: samples are drawn in fixed chunks, each from its own
//! random stream, and summed in chunk order.

use crate::layout::geometry::Geometry;
use crate::raycast::RayCaster;
use crate::scene::Scene;
use crate::trace::Tracer;
use crate::util::sampling::Stream;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Stream purpose id of the meter's samples.
const PURPOSE: u64 = crate::util::sampling::purpose::METER;
/// Samples per chunk (one random stream each).
const CHUNK: u64 = 4096;

/// The meter's reading of one node (one instance of a mesh).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Reading {
    /// The node's name.
    pub node: String,
    /// Its mesh's name.
    pub mesh: String,
    /// World area of the node's triangles (m²).
    pub area: f64,
    /// Points sampled.
    pub samples: u64,
    /// Area-weighted mean incident irradiance / π (linear RGB).
    pub mean: [f64; 3],
    /// Standard error of `mean` per channel.
    pub std_error: [f64; 3],
}

/// The normal a sample point's hemisphere is taken about.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum MeterNormal {
    /// The interpolated `NORMAL` (the smooth surface the mesh stands for).
    #[default]
    Shading,
    /// The triangle's own normal (the facet as modelled; what the bake's
    /// texels use).
    Geometric,
}

/// What to measure, and how.
#[derive(Clone, Debug)]
pub struct MeterSettings {
    /// Sample points per node.
    pub samples: u64,
    /// The normal of each sample point.
    pub normal: MeterNormal,
    /// Sky radiance seen by rays leaving the scene.
    pub sky: Vec3,
    /// Seed of the random streams.
    pub seed: u64,
}

/// The meter over one scene: its world triangles (no atlas), a ray caster
/// and a path tracer.
pub struct Meter<'s> {
    scene: &'s Scene,
    geometry: Geometry,
    rays: RayCaster,
}

impl<'s> Meter<'s> {
    /// A meter over `scene`'s world triangles.
    pub fn new(scene: &'s Scene) -> Self {
        let geometry = Geometry::unmapped(scene);
        let rays = RayCaster::new(scene, &geometry);
        Meter {
            scene,
            geometry,
            rays,
        }
    }

    /// Readings of every instance whose node is named in `nodes` (every
    /// instance with triangles when `nodes` is empty), in instance order.
    ///
    /// # Errors
    /// A name in `nodes` that no instance has.
    pub fn measure(
        &self,
        nodes: &[String],
        settings: &MeterSettings,
    ) -> Result<Vec<Reading>, String> {
        if let Some(missing) = nodes
            .iter()
            .find(|n| !self.scene.instances.iter().any(|i| &i.node == *n))
        {
            return Err(format!("no node named `{missing}`"));
        }
        let mut tracer = Tracer::new(self.scene, &self.geometry, &self.rays, settings.sky);
        // What the lightmap holds: a mixed light's direct light is the
        // engine's (its bounces are measured).
        tracer.skip_mixed_direct = true;
        let mut by_instance: Vec<Vec<u32>> = vec![Vec::new(); self.scene.instances.len()];
        for (t, &i) in self.geometry.instance.iter().enumerate() {
            by_instance[i as usize].push(t as u32);
        }
        Ok(self
            .scene
            .instances
            .iter()
            .enumerate()
            .filter(|(i, inst)| {
                !by_instance[*i].is_empty() && (nodes.is_empty() || nodes.contains(&inst.node))
            })
            .map(|(i, inst)| Reading {
                node: inst.node.clone(),
                mesh: self.scene.meshes[inst.mesh as usize].name.clone(),
                ..self.read(&tracer, i as u64, &by_instance[i], settings)
            })
            .collect())
    }

    /// One instance's reading over triangles `tris` (stream `key`).
    fn read(&self, tracer: &Tracer, key: u64, tris: &[u32], settings: &MeterSettings) -> Reading {
        let g = &self.geometry;
        // Cumulative areas for picking a triangle by area.
        let mut cdf = Vec::with_capacity(tris.len());
        let mut area = 0.0f64;
        for &t in tris {
            area += g.area[t as usize] as f64;
            cdf.push(area);
        }
        let n = settings.samples.max(2);
        let chunks = n.div_ceil(CHUNK);
        let sums: Vec<([f64; 3], [f64; 3])> = (0..chunks)
            .into_par_iter()
            .map(|c| {
                let mut rng = Stream::new(settings.seed, PURPOSE, (key << 32) | c);
                let (mut s, mut sq) = ([0.0f64; 3], [0.0f64; 3]);
                for _ in c * CHUNK..((c + 1) * CHUNK).min(n) {
                    let x = area * rng.next_f32() as f64;
                    let k = cdf.partition_point(|&a| a <= x).min(tris.len() - 1);
                    let (p, normal) =
                        point_on(g, tris[k] as usize, rng.next_vec2(), settings.normal);
                    let h = tracer.incident(p, normal, &mut rng, 0).0;
                    for ch in 0..3 {
                        let v = h[ch] as f64;
                        s[ch] += v;
                        sq[ch] += v * v;
                    }
                }
                (s, sq)
            })
            .collect();
        let (mut s, mut sq) = ([0.0f64; 3], [0.0f64; 3]);
        for (a, b) in &sums {
            for ch in 0..3 {
                s[ch] += a[ch];
                sq[ch] += b[ch];
            }
        }
        let nf = n as f64;
        let mean = s.map(|v| v / nf);
        let std_error = std::array::from_fn(|ch| {
            ((sq[ch] / nf - mean[ch] * mean[ch]).max(0.0) / (nf - 1.0)).sqrt()
        });
        Reading {
            node: String::new(),
            mesh: String::new(),
            area,
            samples: n,
            mean,
            std_error,
        }
    }
}

/// A uniform point on triangle `t` (square-root parametrisation) and its
/// normal: the interpolated shading normal (turned to the triangle's
/// front), or the triangle's own.
fn point_on(g: &Geometry, t: usize, u: Vec2, normal: MeterNormal) -> (Vec3, Vec3) {
    let r = u.x.sqrt();
    let (b1, b2) = (r * (1.0 - u.y), r * u.y);
    let b0 = 1.0 - b1 - b2;
    let [a, b, c] = g.p_ws[t];
    let [na, nb, nc] = g.n_ws[t];
    let p = a * b0 + b * b1 + c * b2;
    let ng = g.ng_ws[t];
    if normal == MeterNormal::Geometric {
        return (p, ng);
    }
    let n = (na * b0 + nb * b1 + nc * b2).normalize_or(ng);
    // A shading normal facing away from the triangle's front would send
    // the hemisphere into the surface.
    (p, if n.dot(ng) > 0.0 { n } else { ng })
}
