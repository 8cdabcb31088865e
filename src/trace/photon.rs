//! Photon mapping (Jensen 1996, "Global Illumination using Photon Maps";
//! Jensen 2001): photons leave the emitters, punctual lights and sky in
//! proportion to their power, bounce diffusely with Russian roulette by
//! albedo, and are stored at every diffuse hit in a kd-tree (`kiddo`).
//! A texel's irradiance is the flux of its k nearest photons over the disc
//! they span, E ≈ Σ Φₚ / (π r²); the texel holds E / π.
//!
//! With `final_gather` > 0 the blotches of the density estimate are hidden
//! by Jensen's final gather: the texel's direct light comes from the same
//! light sampling as the radiosity bake ([`crate::light::direct::texels`]), and its
//! indirect light from `final_gather` cosine rays whose hits report
//! ρ · E_photon / π. Shares the scene, BVH, emitter sampling and texel
//! sampling with the other methods.

use crate::config::BakeConfig;
use crate::light::direct;
use crate::light::lights;
use crate::light::lights::Lights;
use crate::scene::LightKind;
use crate::surface::{Landing, Surfaces};
use crate::trace::Tracer;
use crate::util::sampling::{cosine_hemisphere, offset_ray_origin, stratified, to_world, Stream};
use glam::{Vec2, Vec3};
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use rayon::prelude::*;
use std::f32::consts::PI;
use std::num::NonZero;

/// Stream purpose ids.
const PURPOSE_EMIT: u64 = crate::util::sampling::purpose::PHOTON_EMIT;
const PURPOSE_GATHER: u64 = crate::util::sampling::purpose::PHOTON_GATHER;

/// Photons of one surface orientation count for a query only when their
/// normals are within ~25° of the query's (no light across thin walls or
/// around corners).
const NORMAL_COSINE: f32 = 0.9;

/// A stored photon.
#[derive(Clone, Copy, Debug)]
pub struct Photon {
    /// Where it landed.
    pub p: Vec3,
    /// The surface normal on the side it arrived from.
    pub n: Vec3,
    /// Its flux (W).
    pub flux: Vec3,
}

/// The photon map: photons and a kd-tree over their positions.
pub struct PhotonMap {
    /// Stored photons.
    pub photons: Vec<Photon>,
    tree: ImmutableKdTree<f32, u32, 3, 32>,
    /// Photons emitted.
    pub emitted: u64,
}

/// A light source of the photon emitter, with its share of the power.
#[derive(Clone, Copy, Debug)]
enum Source {
    /// All emissive triangles (then by their own power CDF).
    Area,
    /// Punctual light i.
    Punctual(usize),
    /// The uniform sky.
    Sky,
}

/// Scene bounds (centre, radius) for directional and sky photons.
fn bounds(tracer: &Tracer) -> (Vec3, f32) {
    match tracer.geometry.bounds() {
        Some((lo, hi)) => ((lo + hi) * 0.5, ((hi - lo).length() * 0.5).max(1e-3)),
        None => (Vec3::ZERO, 1.0),
    }
}

/// Uniform point on the unit disk perpendicular to `d`.
fn disk_point(d: Vec3, u: Vec2) -> Vec3 {
    let (t, b) = crate::util::sampling::frame(d);
    let c = crate::util::sampling::concentric_disk(u);
    t * c.x + b * c.y
}

/// Emits `count` photons and stores their diffuse hits.
pub fn trace_photons(tracer: &Tracer, count: u64, seed: u64) -> PhotonMap {
    let (centre, radius) = bounds(tracer);
    let disc = PI * radius * radius;
    let sources = photon_sources(tracer, disc);
    let total: f32 = sources.iter().map(|s| s.1).sum();
    if sources.is_empty() || count == 0 {
        return PhotonMap {
            photons: Vec::new(),
            tree: ImmutableKdTree::new_from_slice(&[]),
            emitted: count,
        };
    }
    let n = count as f32;
    let chunk = 4096u64;
    let parts: Vec<Vec<Photon>> = (0..count.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let mut out = Vec::new();
            for i in c * chunk..((c + 1) * chunk).min(count) {
                let mut rng = Stream::new(seed, PURPOSE_EMIT, i);
                // Pick a source by power.
                let mut x = rng.next_f32() * total;
                let mut pick = sources[sources.len() - 1];
                for s in &sources {
                    if x < s.1 {
                        pick = *s;
                        break;
                    }
                    x -= s.1;
                }
                let p_source = pick.1 / total;
                let u = stratified((i % 64) as u32, 64, rng.next_vec2());
                let v = rng.next_vec2();
                let Some((origin, dir, flux, range)) =
                    emit(tracer, pick.0, (p_source, n), (u, v), (centre, radius))
                else {
                    continue;
                };
                walk(tracer, origin, dir, flux, range, &mut rng, &mut out);
            }
            out
        })
        .collect();
    let photons: Vec<Photon> = parts.into_iter().flatten().collect();
    let points: Vec<[f32; 3]> = photons.iter().map(|p| p.p.to_array()).collect();
    PhotonMap {
        tree: ImmutableKdTree::new_from_slice(&points),
        photons,
        emitted: count,
    }
}

/// Every photon source with its power (W, summed over RGB for the
/// choice): the sampled emitters together, each punctual light, and a
/// uniform sky (`sky_map` is refused with photon mapping) over a disc of
/// area `disc` (the scene's bounding sphere's cross-section).
fn photon_sources(tracer: &Tracer, disc: f32) -> Vec<(Source, f32)> {
    let lights = &tracer.lights;
    // Power of each source (W, summed over RGB for the choice).
    let mut sources: Vec<(Source, f32)> = Vec::new();
    let area_power = PI * lights.cdf.last().copied().unwrap_or(0.0);
    if area_power > 0.0 {
        sources.push((Source::Area, area_power));
    }
    for (i, l) in lights.punctual.iter().enumerate() {
        let power = match l.kind {
            LightKind::Directional => l.intensity.element_sum() * disc,
            LightKind::Point => 4.0 * PI * l.intensity.element_sum(),
            LightKind::Spot {
                outer_cone_angle, ..
            } => 2.0 * PI * (1.0 - outer_cone_angle.cos()) * l.intensity.element_sum(),
        };
        if power > 0.0 {
            sources.push((Source::Punctual(i), power));
        }
    }
    // A uniform sky (`sky_map` is refused with photon mapping).
    let sky = lights.sky.mean();
    let sky_power = 4.0 * PI * disc * sky.element_sum();
    if sky_power > 0.0 {
        sources.push((Source::Sky, sky_power));
    }
    sources
}

/// One photon leaving `source`: its origin, direction, flux (the
/// source's radiance or intensity over the pdf of the choice: the
/// source's probability `p_source` × the `n` photons emitted × the
/// direction's or point's pdf) and range (a punctual light's), from the
/// stratified `u` and the uniform `v`; None where an emitter sample fails.
fn emit(
    tracer: &Tracer,
    source: Source,
    (p_source, n): (f32, f32),
    (u, v): (Vec2, Vec2),
    (centre, radius): (Vec3, f32),
) -> Option<(Vec3, Vec3, Vec3, Option<f32>)> {
    let (g, lights) = (tracer.geometry, &tracer.lights);
    let disc = PI * radius * radius;
    let mut range = None;
    let (origin, dir, flux) = match source {
        Source::Area => {
            let ls = lights.sample(g, u)?;
            let le = tracer
                .scene
                .emission_at(g.material[ls.tri as usize], g.uv0_at(ls.tri, ls.u, ls.v));
            let d = to_world(cosine_hemisphere(v), ls.normal);
            // Le cos / (p_A · cos/π) = Le π / p_A.
            (
                offset_ray_origin(ls.point, ls.normal),
                d,
                le * PI / (ls.pdf_area * p_source * n),
            )
        }
        Source::Punctual(k) => {
            let l = &lights.punctual[k];
            match l.kind {
                LightKind::Directional => {
                    let d = l.direction.normalize();
                    let o = centre - d * (2.0 * radius) + disk_point(d, u) * radius;
                    (o, d, l.intensity * disc / (p_source * n))
                }
                LightKind::Point | LightKind::Spot { .. } => {
                    // Uniform over the sphere (point) or the outer cone (spot).
                    let cos_max = match l.kind {
                        LightKind::Spot {
                            outer_cone_angle, ..
                        } => outer_cone_angle.cos(),
                        _ => -1.0,
                    };
                    let z = 1.0 - u.x * (1.0 - cos_max);
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let phi = 2.0 * PI * u.y;
                    let local = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    let d = to_world(local, l.direction.normalize());
                    let pdf = 1.0 / (2.0 * PI * (1.0 - cos_max));
                    // Intensity towards d (cone falloff) from the
                    // shared punctual evaluation at unit distance.
                    let bare = crate::scene::Light {
                        range: None,
                        ..l.clone()
                    };
                    let i_d = lights::punctual_irradiance(&bare, l.position + d, -d)
                        .map_or(Vec3::ZERO, |(h, _, _)| h * PI);
                    range = l.range.filter(|r| *r > 0.0);
                    (l.position, d, i_d / (pdf * p_source * n))
                }
            }
        }
        Source::Sky => {
            // Incoming direction uniform over the sphere, origin
            // on a disc of the bounding sphere's radius.
            let z = 1.0 - 2.0 * v.x;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * PI * v.y;
            let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            let o = centre - d * (2.0 * radius) + disk_point(d, u) * radius;
            let sky = lights.sky.mean();
            (o, d, sky * (4.0 * PI * disc) / (p_source * n))
        }
    };
    Some((origin, dir, flux, range))
}

/// Follows one photon, storing it at each diffuse hit.
fn walk(
    tracer: &Tracer,
    mut origin: Vec3,
    mut dir: Vec3,
    mut flux: Vec3,
    range: Option<f32>,
    rng: &mut Stream,
    out: &mut Vec<Photon>,
) {
    let g = tracer.geometry;
    for bounce in 0..64 {
        let Some(hit) = tracer.rays.closest_hit(origin, dir, f32::INFINITY) else {
            return;
        };
        // A punctual light's range window (KHR_lights_punctual) acts on
        // the first segment, as in the direct light.
        if let (0, Some(r)) = (bounce, range) {
            flux *= (1.0 - (hit.t / r).powi(4)).clamp(0.0, 1.0);
        }
        let tri = hit.tri as usize;
        let m = g.material[tri];
        let ng = g.ng_ws[tri];
        let front = ng.dot(dir) < 0.0;
        if !front && !tracer.scene.materials[m as usize].double_sided {
            return;
        }
        let n = if front { ng } else { -ng };
        let p = g.point(hit.tri, hit.u, hit.v);
        out.push(Photon { p, n, flux });
        let albedo = tracer.scene.albedo_at(m, g.uv0_at(hit.tri, hit.u, hit.v)).0;
        let q = albedo.max_element().clamp(0.0, 0.95);
        if q <= 0.0 || rng.next_f32() >= q {
            return;
        }
        flux *= albedo / q;
        dir = to_world(cosine_hemisphere(rng.next_vec2()), n);
        origin = offset_ray_origin(p, n);
    }
}

/// Irradiance precomputed at a subset of the photons (Christensen 1999,
/// "Faster Photon Map Global Illumination"): final-gather hits take the
/// nearest precomputed value with a matching normal instead of a k-nearest
/// search each.
pub struct Precomputed {
    points: Vec<(Vec3, Vec3)>,
    values: Vec<Vec3>,
    tree: ImmutableKdTree<f32, u32, 3, 32>,
}

impl Precomputed {
    /// Estimates at every `stride`-th photon with `k` neighbours.
    pub fn new(map: &PhotonMap, k: usize, stride: usize) -> Precomputed {
        let points: Vec<(Vec3, Vec3)> = map
            .photons
            .iter()
            .step_by(stride.max(1))
            .map(|p| (p.p, p.n))
            .collect();
        let values = points
            .par_iter()
            .map(|&(p, n)| map.estimate(p, n, k))
            .collect();
        let xyz: Vec<[f32; 3]> = points.iter().map(|p| p.0.to_array()).collect();
        Precomputed {
            tree: ImmutableKdTree::new_from_slice(&xyz),
            points,
            values,
        }
    }

    /// Irradiance / π of the nearest precomputed point whose normal matches
    /// `n` (among the 8 nearest), else zero.
    pub fn lookup(&self, p: Vec3, n: Vec3) -> Vec3 {
        let Some(k) = NonZero::new(8.min(self.points.len())) else {
            return Vec3::ZERO;
        };
        self.tree
            .nearest_n::<SquaredEuclidean>(&p.to_array(), k)
            .iter()
            .find(|f| self.points[f.item as usize].1.dot(n) > NORMAL_COSINE)
            .map_or(Vec3::ZERO, |f| self.values[f.item as usize])
    }
}

impl PhotonMap {
    /// Irradiance / π at `p` (normal `n`) from the `k` nearest photons.
    pub fn estimate(&self, p: Vec3, n: Vec3, k: usize) -> Vec3 {
        if self.photons.is_empty() {
            return Vec3::ZERO;
        }
        let Some(k) = NonZero::new(k.min(self.photons.len())) else {
            return Vec3::ZERO;
        };
        let found = self.tree.nearest_n::<SquaredEuclidean>(&p.to_array(), k);
        // The disc is the one the matching photons span: photons of other
        // orientations (a wall meeting this floor) neither count nor widen it.
        let (mut flux, mut r2) = (Vec3::ZERO, 0.0f32);
        for f in &found {
            let ph = &self.photons[f.item as usize];
            if ph.n.dot(n) > NORMAL_COSINE {
                flux += ph.flux;
                r2 = r2.max(f.distance);
            }
        }
        if r2 <= 0.0 {
            return Vec3::ZERO;
        }
        flux / (PI * r2) / PI
    }
}

/// Texel values by photon mapping (see the module doc). Returns (values,
/// validity, photons emitted + gather rays).
pub fn bake_texels(
    s: &Surfaces,
    tracer: &Tracer,
    config: &BakeConfig,
    advance: &(dyn Fn(u64) + Sync),
) -> (Vec<Vec3>, Vec<bool>, u64) {
    let map = trace_photons(tracer, config.photons, config.seed);
    let k = config.photon_neighbours as usize;
    let n = s.texels.len();
    if config.final_gather == 0 {
        // Validity as in the final gather, from 16 rays per texel: texels
        // inside or under geometry are filled from their neighbours.
        const PROBES: u32 = 16;
        let (values, valid): (Vec<Vec3>, Vec<bool>) = (0..n)
            .into_par_iter()
            .map(|t| {
                let mut rng = Stream::new(config.seed, PURPOSE_GATHER, t as u64);
                let back = (0..PROBES)
                    .filter(|&j| {
                        let (p, ng) =
                            s.sample_texel(t as u32, stratified(j, PROBES, rng.next_vec2()));
                        let dir = to_world(cosine_hemisphere(rng.next_vec2()), ng);
                        matches!(s.trace(offset_ray_origin(p, ng), dir).0, Landing::BackFace)
                    })
                    .count();
                let valid =
                    back as f32 <= crate::surface::validity::BACKFACE_TOLERANCE * PROBES as f32;
                (map.estimate(s.texels.p_ws[t], s.texels.n_ws[t], k), valid)
            })
            .unzip();
        advance(n as u64);
        return (values, valid, config.photons + n as u64 * PROBES as u64);
    }
    // Direct light as the radiosity bake computes it (every emitter sampled).
    let all = vec![true; s.scene.materials.len()];
    let lights = Lights::new(s.scene, s.geometry, &all, tracer.lights.sky.clone());
    let n_direct = config.direct_samples;
    let mis = lights::Mis {
        light: n_direct,
        hemisphere: n_direct,
    };
    let direct = direct::texels(
        s,
        &lights,
        n_direct,
        n_direct,
        mis,
        config.supersample,
        config.seed,
        &|_| {},
    )
    .baked();
    let rays = config.final_gather;
    // At most ~64 k precomputed points (each a k-nearest search).
    let pre = Precomputed::new(&map, k, (map.photons.len() / 65536).max(4));
    let out: Vec<(Vec3, bool)> = (0..n)
        .into_par_iter()
        .map(|t| {
            let mut rng = Stream::new(config.seed, PURPOSE_GATHER, t as u64);
            let (mut sum, mut back) = (Vec3::ZERO, 0u32);
            for j in 0..rays {
                let (p, ng) = s.sample_texel(t as u32, stratified(j, rays, rng.next_vec2()));
                let dir = to_world(cosine_hemisphere(rng.next_vec2()), ng);
                match s.trace(offset_ray_origin(p, ng), dir) {
                    (Landing::BackFace, _) => back += 1,
                    (Landing::Escaped, _) => {}
                    (_, Some(hit)) => {
                        let g = s.geometry;
                        let tri = hit.tri as usize;
                        let m = g.material[tri];
                        let albedo = s.scene.albedo_at(m, g.uv0_at(hit.tri, hit.u, hit.v)).0;
                        let front = g.ng_ws[tri].dot(dir) < 0.0;
                        let nh = if front { g.ng_ws[tri] } else { -g.ng_ws[tri] };
                        let q = g.point(hit.tri, hit.u, hit.v);
                        // Emitters and sky are in the direct light already.
                        sum += albedo * pre.lookup(q, nh);
                    }
                    _ => {}
                }
            }
            let valid = back as f32 <= crate::surface::validity::BACKFACE_TOLERANCE * rays as f32;
            (direct[t] + sum / rays as f32, valid)
        })
        .collect();
    advance(n as u64);
    let (values, valid) = out.into_iter().unzip();
    (values, valid, config.photons + n as u64 * rays as u64)
}
