//! The light at one probe: incident radiance over the whole sphere, all
//! bounces, projected onto L2 SH ([`super::sh`]):
//! Lₗₘ = ∫ L(ω) Yₗₘ(ω) dω.
//!
//! - **Rays** in a spherical Fibonacci set (Keinert et al. 2015), turned by
//!   a random rotation per probe, each of weight 4π/N: a set whose sums of
//!   Yₗₘ are near zero for l ≥ 1, so a uniform field projects to its DC
//!   term alone. A ray that meets a surface reads its outgoing radiance as
//!   the final gather does: the hit texel's albedo × its lightmap value
//!   (incident irradiance / π, every bounce), plus emission where the
//!   emitter is not sampled; a ray that leaves sees the sky.
//! - **Emitters** whose emission the direct pass samples are sampled here
//!   too, by power, and the two estimators are combined by the power
//!   heuristic with sample counts (Veach 1997 §9.2), as in the direct pass.
//!   The sky is uniform, so the sphere rays, uniform in solid angle, are
//!   already its ideal sampling: a second strategy would have the same pdf
//!   and MIS would weight the two equally.
//! - **Punctual lights** enter exactly: a delta direction of irradiance E
//!   projects to E · Yₗₘ(ω_light), shadowed by one ray.
//! - **Validity**: a probe whose rays meet more than a quarter back faces
//!   is inside a solid (as Unreal judges distance-field signs).

use super::sh::{self, Sh9};
use crate::light::lights::{light_visibility, punctual_incident, punctual_unoccluded, Lights, Mis};
use crate::surface::{Landing, Surfaces};
use crate::util::sampling::{Net, Stream};
use glam::{Quat, Vec3};

/// Stream purpose id of probe rays.
const PURPOSE: u64 = crate::util::sampling::purpose::PROBES;

/// A probe is invalid when more than this fraction of its rays meet back
/// faces.
pub const BACKFACE_TOLERANCE: f32 = 0.25;

/// What every probe reads.
pub struct ProbeLight<'a> {
    /// The surfaces the rays meet.
    pub s: &'a Surfaces<'a>,
    /// Outgoing diffuse radiance per texel: albedo × lightmap value.
    pub radiance: Vec<Vec3>,
    /// Per material: emission sampled as a light (else read by the rays).
    pub sampled: &'a [bool],
    /// The emitters, punctual lights and sky.
    pub lights: &'a Lights,
    /// Rays per probe.
    pub rays: u32,
    /// Emitter samples per probe (when there are emitters).
    pub light_samples: u32,
    /// The bake's seed.
    pub seed: u64,
}

/// One probe's result.
#[derive(Clone, Copy, Debug)]
pub struct ProbeSample {
    /// Radiance SH.
    pub sh: Sh9,
    /// False when inside a solid.
    pub valid: bool,
    /// Rays cast (sphere, light samples, punctual shadow rays).
    pub rays: u32,
}

/// Direction `i` of a spherical Fibonacci set of `n` (Keinert et al. 2015;
/// [`radbake_live::probes::fibonacci`], which the live probes share).
pub fn fibonacci(i: u32, n: u32) -> Vec3 {
    Vec3::from(radbake_live::probes::fibonacci(i, n))
}

/// A uniformly random rotation (Shoemake 1992, "Uniform random rotations").
fn random_rotation(rng: &mut Stream) -> Quat {
    let (u1, u2, u3) = (rng.next_f32(), rng.next_f32(), rng.next_f32());
    let tau = 2.0 * std::f32::consts::PI;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    Quat::from_xyzw(
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
        b * (tau * u3).cos(),
    )
    .normalize()
}

/// `sky_mis.light` samples of a sky map from probe `p` (a Hammersley set
/// turned at random, through the map's luminance distribution), each
/// unoccluded one added to `sh` with the light estimator's MIS weight
/// against the sphere rays (power heuristic with counts), its radiance
/// times `scale` (a light layer's share of the sky); and into each of
/// `layers` with its share of `shares`. Returns the shadow rays cast.
fn sky_samples(
    s: &Surfaces,
    map: &crate::light::sky::SkyMap,
    (p, scale, shares): (Vec3, f32, &[f32]),
    sky_mis: Mis,
    rng: &mut Stream,
    (sh, layers): (&mut Sh9, &mut [Sh9]),
) -> u32 {
    let ms = sky_mis.light;
    let shift = rng.next_vec2();
    let mut cast = 0;
    for k in 0..ms {
        let (dir, pdf, l) = map.sample(crate::util::sampling::hammersley(k, ms, shift));
        if pdf <= 0.0 {
            continue;
        }
        cast += 1;
        if s.rays.unoccluded(p, dir, f32::INFINITY) {
            let p_b = 1.0 / (4.0 * std::f32::consts::PI);
            let w = 1.0 - sky_mis.hemisphere_weight(pdf, p_b);
            sh::add(sh, dir, l * (w * scale), 1.0 / (pdf * ms as f32));
            for (share, sh) in shares.iter().zip(layers.iter_mut()) {
                sh::add(sh, dir, l * (w * share), 1.0 / (pdf * ms as f32));
            }
        }
    }
    cast
}

/// What a probe's sphere ray met ([`ProbeLight::along`]), for the light
/// layers to read their share of.
#[derive(Clone, Copy)]
pub enum Met {
    /// A back face, or nothing that brings light.
    Nothing,
    /// The sky: its radiance and the ray's MIS weight.
    Sky(Vec3, f32),
    /// A surface: the texel it landed on, and its emission (before any
    /// layer's share) with the material and, for a sampled emitter, the
    /// ray's MIS weight.
    Surface(Option<u32>, Option<(Vec3, u32, Option<f32>)>),
}

/// A light layer's view of the probes ([`ProbeLight::probe_layers`]): its
/// surfaces' outgoing radiance and its share of each light.
pub struct LayerProbe<'a> {
    /// Outgoing diffuse radiance per texel: albedo × the layer's lightmap
    /// value.
    pub radiance: Vec<Vec3>,
    /// The layer's masked lights ([`Lights::masked`]).
    pub lights: &'a Lights,
}

impl LayerProbe<'_> {
    /// The radiance the layer receives along a ray that met `met`: as
    /// [`ProbeLight::along`] computes it over the layer's lights.
    fn along(&self, met: Met) -> Vec3 {
        match met {
            Met::Nothing => Vec3::ZERO,
            Met::Sky(sky, w) => sky * self.lights.sky_weight() * w,
            Met::Surface(texel, emitted) => {
                let mut l = texel.map_or(Vec3::ZERO, |t| self.radiance[t as usize]);
                if let Some((e, mat, mis)) = emitted {
                    let le = e * self.lights.emission_weight(mat);
                    match mis {
                        None => l += le,
                        Some(w) => l += le * w,
                    }
                }
                l
            }
        }
    }
}

impl ProbeLight<'_> {
    /// The light at probe `index`, at world position `p`.
    pub fn probe(&self, index: usize, p: Vec3) -> ProbeSample {
        self.probe_layers(index, p, &[], &mut [])
    }

    /// [`ProbeLight::probe`], and in the same pass each light layer's SH
    /// into `out` (one per layer of `layers`): every ray, light sample
    /// and shadow ray the whole probe casts, read for each layer with its
    /// radiance and its share of each light ([`LayerProbe`]), each value
    /// the product a pass over the layer's masked lights computes.
    pub fn probe_layers(
        &self,
        index: usize,
        p: Vec3,
        layers: &[LayerProbe],
        out: &mut [Sh9],
    ) -> ProbeSample {
        let mut rng = Stream::new(self.seed, PURPOSE, index as u64);
        let turn = random_rotation(&mut rng);
        let net = Net::new(&mut rng);
        let mut sh: Sh9 = [Vec3::ZERO; 9];
        let n = self.rays.max(1);
        let m = if self.lights.emitters.is_empty() {
            0
        } else {
            self.light_samples
        };
        let mis = Mis {
            light: m,
            hemisphere: n,
        };
        // A sky map is sampled too (`sky_samples` per probe).
        let map = self.lights.sky.map().filter(|m| !m.is_black());
        let sky_mis = Mis {
            light: if map.is_some() {
                self.lights.sky_samples
            } else {
                0
            },
            hemisphere: n,
        };
        let w = 4.0 * std::f32::consts::PI / n as f32;
        let mut back = 0u32;
        let mut cast = 0u32;
        for i in 0..n {
            let d = turn * fibonacci(i, n);
            cast += 1;
            let (l, backface, met) = self.along(p, d, mis, sky_mis);
            back += backface as u32;
            sh::add(&mut sh, d, l, w);
            for (layer, sh) in layers.iter().zip(out.iter_mut()) {
                sh::add(sh, d, layer.along(met), w);
            }
        }
        for k in 0..m {
            let (shot, seen) = self.light_sample(p, net.point(k), mis, &mut sh);
            cast += shot as u32;
            if let Some((d, e, mat, weight)) = seen {
                for (layer, sh) in layers.iter().zip(out.iter_mut()) {
                    sh::add(sh, d, e * layer.lights.emission_weight(mat), weight);
                }
            }
        }
        if let Some(map) = map {
            let scale = self.lights.sky_weight();
            let shares: Vec<f32> = layers.iter().map(|l| l.lights.sky_weight()).collect();
            cast += sky_samples(self.s, map, (p, scale, &shares), sky_mis, &mut rng, (&mut sh, out));
        }
        // Mixed lights' direct light is the engine's to draw.
        for (i, light) in self.lights.punctual.iter().enumerate() {
            if light.mode.is_mixed() {
                continue;
            }
            if let Some((e0, to, dist)) = punctual_incident(light, p) {
                let e = e0 * self.lights.punctual_weight(i);
                let visible = if light.has_extent() {
                    // A sphere or sun disk: its visible fraction over its
                    // extent, the delta kept at its centre.
                    let from = [(p, to, 1.0, to, dist)];
                    let (visible, rays) = light_visibility(self.s.rays, light, &from, &mut rng);
                    cast += rays as u32;
                    sh::add(&mut sh, to, e * visible, 1.0);
                    Some(visible)
                } else {
                    cast += 1;
                    let seen = punctual_unoccluded(self.s.rays, p, to, dist);
                    if seen {
                        sh::add(&mut sh, to, e, 1.0);
                    }
                    seen.then_some(1.0)
                };
                for (layer, sh) in layers.iter().zip(out.iter_mut()) {
                    let e = e0 * layer.lights.punctual_weight(i);
                    match visible {
                        Some(v) if light.has_extent() => sh::add(sh, to, e * v, 1.0),
                        Some(_) => sh::add(sh, to, e, 1.0),
                        None => {}
                    }
                }
            }
        }
        ProbeSample {
            sh,
            valid: back as f32 <= BACKFACE_TOLERANCE * n as f32,
            rays: cast,
        }
    }

    /// Radiance arriving at `p` from direction `d` (the sphere estimator's
    /// part: sampled emitters MIS-weighted), and whether a back face was met.
    fn along(&self, p: Vec3, d: Vec3, mis: Mis, sky_mis: Mis) -> (Vec3, bool, Met) {
        let s = self.s;
        let g = s.geometry;
        let (landing, hit) = s.trace(p, d);
        let Some(hit) = hit else {
            let sky = self.lights.sky.radiance(d);
            let l = sky * self.lights.sky_weight();
            let w = match self.lights.sky.map() {
                Some(map) if sky_mis.light > 0 => {
                    sky_mis.hemisphere_weight(map.pdf(d), 1.0 / (4.0 * std::f32::consts::PI))
                }
                _ => 1.0,
            };
            return (l * w, false, Met::Sky(sky, w));
        };
        if let Landing::BackFace = landing {
            return (Vec3::ZERO, true, Met::Nothing);
        }
        let tri = hit.tri as usize;
        let mat = g.material[tri];
        let texel = match landing {
            Landing::Texel(t) => Some(t),
            _ => None,
        };
        let mut l = texel.map_or(Vec3::ZERO, |t| self.radiance[t as usize]);
        let mut emitted = None;
        if g.ng_ws[tri].dot(d) < 0.0 && s.scene.materials[mat as usize].is_emissive() {
            let e = s.scene.emission_at(mat, g.uv0_at(hit.tri, hit.u, hit.v));
            let le = e * self.lights.emission_weight(mat);
            if !self.sampled[mat as usize] {
                l += le;
                emitted = Some((e, mat, None));
            } else if let Some(k) = self.lights.emitter_index(hit.tri) {
                let p_l = self
                    .lights
                    .pdf_solid_angle(g, k, p, p + d * hit.t, g.ng_ws[tri]);
                let p_b = 1.0 / (4.0 * std::f32::consts::PI);
                let w = mis.hemisphere_weight(p_l, p_b);
                l += le * w;
                emitted = Some((e, mat, Some(w)));
            }
        }
        (l, false, Met::Surface(texel, emitted))
    }

    /// One emitter sample for unit-square point `u`, MIS-weighted, added to
    /// `sh`. Returns whether a shadow ray was cast.
    /// Also what a light layer adds from it where it was seen: its
    /// direction, the emission (before any layer's share), the material
    /// and the SH weight.
    #[allow(clippy::type_complexity)]
    fn light_sample(
        &self,
        p: Vec3,
        u: glam::Vec2,
        mis: Mis,
        sh: &mut Sh9,
    ) -> (bool, Option<(Vec3, Vec3, u32, f32)>) {
        let (s, g) = (self.s, self.s.geometry);
        let Some(e) = self.lights.sample(g, u) else {
            return (false, None);
        };
        let to = e.point - p;
        let dist = to.length();
        if dist <= 0.0 {
            return (false, None);
        }
        let d = to / dist;
        let cos_q = e.normal.dot(-d);
        if cos_q <= 0.0 {
            return (false, None);
        }
        let p_l = e.pdf_area * dist * dist / cos_q;
        if !punctual_unoccluded(s.rays, p, d, dist) {
            return (true, None);
        }
        let mat = g.material[e.tri as usize];
        let emitted = s.scene.emission_at(mat, g.uv0_at(e.tri, e.u, e.v));
        let le = emitted * self.lights.emission_weight(mat);
        let p_b = 1.0 / (4.0 * std::f32::consts::PI);
        let w_l = 1.0 - mis.hemisphere_weight(p_l, p_b);
        let weight = w_l / (mis.light as f32 * p_l);
        sh::add(sh, d, le, weight);
        (true, Some((d, emitted, mat, weight)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Fibonacci set's first-band sums vanish (to O(1/N)), which is
    /// what keeps a uniform field's higher bands at zero.
    #[test]
    fn fibonacci_set_is_balanced() {
        let n = 1024;
        let mut sum = Vec3::ZERO;
        let mut yy = [0.0f32; 9];
        for i in 0..n {
            let d = fibonacci(i, n);
            assert!((d.length() - 1.0).abs() < 1e-5);
            sum += d;
            for (a, b) in yy.iter_mut().zip(sh::basis(d)) {
                *a += b;
            }
        }
        assert!(sum.length() / (n as f32) < 1e-3, "{sum}");
        for (k, v) in yy.iter().enumerate().skip(1) {
            assert!((v / n as f32).abs() < 2e-3, "band sum {k}: {v}");
        }
    }

    #[test]
    fn rotations_are_rotations() {
        let mut rng = Stream::new(3, 0, 0);
        for _ in 0..100 {
            let q = random_rotation(&mut rng);
            assert!((q.length() - 1.0).abs() < 1e-5);
        }
    }
}
