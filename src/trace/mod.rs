//! Path tracing: the rendering equation solved by random walks over the same
//! scene, BVH, emitters and sampling code as the radiosity bake, for two
//! jobs — an independent oracle for the bake (reference lightmaps and
//! reference images) and a final-quality render that reads the lightmaps.
//!
//! The physics is the baker's: Lambertian surfaces of albedo ρ (textured),
//! emissive fronts of radiance E, `KHR_lights_punctual` lights, a uniform
//! sky seen by rays that leave the scene, one-sided surfaces black from
//! behind. Perfect mirrors and glass ([`Specular`]) are followed
//! recursively (Whitted 1980); the radiosity bake treats them as Lambertian.
//!
//! The core estimator is [`Tracer::incident`], an unbiased estimate of
//! H/π = (1/π) ∫ L_i(ω) cos θ dω at a diffuse point — exactly what a
//! lightmap texel holds — with next-event estimation (Kajiya 1986):
//! punctual lights by one shadow ray each; emitters by one light sample and
//! one cosine-weighted hemisphere sample combined with the balance heuristic
//! (Veach & Guibas 1995); the hemisphere sample continues the path, where the
//! outgoing radiance of a diffuse hit is E + ρ · H/π there (recursively,
//! with Russian roulette), or, in final-pass mode, E + ρ × the lightmap.

pub mod bdpt;
pub mod measure;
pub mod photon;
pub mod reference;
pub mod render;
pub mod sphere;
pub mod view;

use crate::layout::geometry::Geometry;
use crate::light::lights::{extent_sample, punctual_irradiance, punctual_unoccluded, Lights};
use crate::raycast::RayCaster;
use crate::scene::{Scene, Specular};
use crate::util::sampling::{cosine_hemisphere, offset_ray_origin, shadow_ray, to_world, Stream};
use glam::{Vec2, Vec3};

/// Longest chain of specular bounces followed before a path is cut (a
/// faceted glass sphere traps a few per cent of paths for over 16).
const MAX_SPECULAR: u32 = 256;

/// Lightmap pages to read at the hits of final-pass gather rays.
#[derive(Clone, Copy, Debug)]
pub struct LightmapLookup<'a> {
    /// Page width (texels).
    pub width: u32,
    /// Page height (texels).
    pub height: u32,
    /// Row-major irradiance / π per page (dilated, as written).
    pub pages: &'a [Vec<Vec3>],
}

impl LightmapLookup<'_> {
    /// Bilinear lookup at `uv` in texel units (texel (x, y) covers
    /// [x, x+1) × [y, y+1), its value sits at its centre), clamped to the page.
    pub fn at(&self, page: u32, uv: Vec2) -> Vec3 {
        let Some(values) = self.pages.get(page as usize) else {
            return Vec3::ZERO;
        };
        let (w, h) = (self.width as i64, self.height as i64);
        let q = uv - Vec2::splat(0.5);
        let (x0, y0) = (q.x.floor(), q.y.floor());
        let (fx, fy) = (q.x - x0, q.y - y0);
        let texel = |x: i64, y: i64| {
            let x = x.clamp(0, w - 1);
            let y = y.clamp(0, h - 1);
            values[(y * w + x) as usize]
        };
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = texel(x0, y0) * (1.0 - fx) + texel(x0 + 1, y0) * fx;
        let bottom = texel(x0, y0 + 1) * (1.0 - fx) + texel(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// A ray's first diffuse landing after any specular chain.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Landing {
    /// Point (world).
    pub p: Vec3,
    /// Geometric normal on the side the ray arrived from.
    pub n: Vec3,
    /// Triangle.
    pub tri: u32,
    /// Barycentrics.
    pub u: f32,
    /// See `u`.
    pub v: f32,
    /// True when the ray hit the front (emitting) side.
    pub front: bool,
}

/// What a ray (followed through mirrors and glass) reaches.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Reach {
    /// A diffuse surface, with the throughput of the specular chain and
    /// whether the chain was empty (MIS with light sampling applies).
    Diffuse(Landing, Vec3, bool),
    /// The back of a one-sided surface (black, and a sign of a texel
    /// inside geometry when it is the first hit).
    Back,
    /// The sky, with the chain's throughput, the direction it arrives
    /// from (reversed) and whether the chain was empty (MIS with the sky
    /// map's light samples applies).
    Sky(Vec3, Vec3, bool),
    /// Nothing (path cut or absorbed).
    Nothing,
}

/// The scene prepared for path tracing.
pub struct Tracer<'a> {
    /// Materials and textures.
    pub scene: &'a Scene,
    /// World triangles.
    pub geometry: &'a Geometry,
    /// BVH.
    pub rays: &'a RayCaster,
    /// Every emissive triangle (sampled by power), punctual lights, sky.
    pub lights: Lights,
    /// The first diffuse vertex (depth 0: a texel) leaves the mixed
    /// lights' direct light out, as the lightmap does
    /// ([`crate::scene::LightMode::is_mixed`]); their light still arrives
    /// at every later vertex.
    pub skip_mixed_direct: bool,
    /// Final-pass mode: the lightmaps read at gather hits.
    pub lightmaps: Option<LightmapLookup<'a>>,
    /// Russian roulette starts after this many diffuse bounces.
    pub rr_depth: u32,
    /// Hard limit on diffuse bounces (a bias below ρ^64 in practice).
    pub max_depth: u32,
}

impl<'a> Tracer<'a> {
    /// A tracer over `geometry` whose every emissive triangle is a light.
    pub fn new(
        scene: &'a Scene,
        geometry: &'a Geometry,
        rays: &'a RayCaster,
        sky: impl Into<crate::light::sky::Sky>,
    ) -> Self {
        let all = vec![true; scene.materials.len()];
        Tracer {
            scene,
            geometry,
            rays,
            lights: Lights::new(scene, geometry, &all, sky),
            skip_mixed_direct: false,
            lightmaps: None,
            rr_depth: 3,
            max_depth: 64,
        }
    }

    /// Follows `origin + t·dir` through perfect mirrors and glass until it
    /// reaches a diffuse surface, the sky, or the back of a one-sided surface.
    /// Also returns the emission of the specular surfaces met on the way
    /// (× the chain's throughput); `mis_from`, the diffuse point and normal
    /// the ray left by cosine sampling, weights an emissive first hit
    /// against light sampling (balance heuristic).
    pub(crate) fn reach(
        &self,
        mut origin: Vec3,
        mut dir: Vec3,
        rng: &mut Stream,
        mis_from: Option<(Vec3, Vec3)>,
    ) -> (Reach, Vec3) {
        let g = self.geometry;
        let mut throughput = Vec3::ONE;
        let mut glow = Vec3::ZERO;
        for bounce in 0..=MAX_SPECULAR {
            let Some(hit) = self.rays.closest_hit(origin, dir, f32::INFINITY) else {
                return (Reach::Sky(throughput, dir, bounce == 0), glow);
            };
            let tri = hit.tri as usize;
            let m = g.material[tri];
            let material = &self.scene.materials[m as usize];
            let ng = g.ng_ws[tri];
            let front = ng.dot(dir) < 0.0;
            let p = g.point(hit.tri, hit.u, hit.v);
            let facing = if front { ng } else { -ng };
            if material.specular != Specular::None && front && material.is_emissive() {
                let le = self.scene.emission_at(m, g.uv0_at(hit.tri, hit.u, hit.v));
                let w = match (bounce, mis_from, self.lights.emitter_index(hit.tri)) {
                    (0, Some((from, n)), Some(k)) => {
                        let p_b = n.dot(dir) / std::f32::consts::PI;
                        let p_l = self.lights.pdf_solid_angle(g, k, from, p, ng);
                        p_b / (p_b + p_l)
                    }
                    _ => 1.0,
                };
                glow += throughput * le * w;
            }
            match material.specular {
                Specular::None => {
                    if !front && !material.double_sided {
                        return (Reach::Back, glow);
                    }
                    return (
                        Reach::Diffuse(
                            Landing {
                                p,
                                n: facing,
                                tri: hit.tri,
                                u: hit.u,
                                v: hit.v,
                                front,
                            },
                            throughput,
                            bounce == 0,
                        ),
                        glow,
                    );
                }
                Specular::Mirror => {
                    if !front && !material.double_sided {
                        return (Reach::Back, glow);
                    }
                    let tint = self.scene.albedo_at(m, g.uv0_at(hit.tri, hit.u, hit.v)).0;
                    throughput *= tint;
                    dir = dir - facing * (2.0 * dir.dot(facing));
                    origin = offset_ray_origin(p, facing);
                }
                Specular::Glass { ior } => {
                    let cos_i = -dir.dot(facing);
                    let eta = if front { 1.0 / ior } else { ior };
                    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
                    let reflectance = if sin2_t >= 1.0 {
                        1.0
                    } else {
                        let cos_t = (1.0 - sin2_t).sqrt();
                        fresnel_dielectric(cos_i, cos_t, eta)
                    };
                    if rng.next_f32() < reflectance {
                        dir += facing * (2.0 * cos_i);
                        origin = offset_ray_origin(p, facing);
                    } else {
                        let cos_t = (1.0 - sin2_t).sqrt();
                        dir = (dir * eta + facing * (eta * cos_i - cos_t)).normalize();
                        throughput *= self.scene.albedo_at(m, g.uv0_at(hit.tri, hit.u, hit.v)).0;
                        origin = offset_ray_origin(p, -facing);
                    }
                }
            }
            if throughput.max_element() <= 0.0 {
                return (Reach::Nothing, glow);
            }
        }
        (Reach::Nothing, glow)
    }

    /// Radiance arriving at `p` along −`dir` from a ray that leaves the
    /// diffuse point `p` (normal `n`) in the cosine-sampled direction `dir`,
    /// with the balance-heuristic weight for emitters that light sampling
    /// could also have found. Returns (radiance, hit a back face first).
    fn gathered(&self, p: Vec3, n: Vec3, dir: Vec3, rng: &mut Stream, depth: u32) -> (Vec3, bool) {
        let g = self.geometry;
        let (reach, glow) = self.reach(offset_ray_origin(p, n), dir, rng, Some((p, n)));
        let (l, back) = match reach {
            Reach::Sky(t, d, direct) => {
                let l = self.lights.sky.radiance(d);
                // Balance heuristic against the sky map's light sample.
                let w = match (direct, self.lights.sky.map()) {
                    (true, Some(map)) => {
                        let p_b = n.dot(d) / std::f32::consts::PI;
                        p_b / (p_b + map.pdf(d))
                    }
                    _ => 1.0,
                };
                (t * l * w, false)
            }
            Reach::Back => (Vec3::ZERO, true),
            Reach::Nothing => (Vec3::ZERO, false),
            Reach::Diffuse(hit, t, direct) => {
                let m = g.material[hit.tri as usize];
                let uv0 = g.uv0_at(hit.tri, hit.u, hit.v);
                let mut l = Vec3::ZERO;
                if hit.front {
                    let le = self.scene.emission_at(m, uv0);
                    if le != Vec3::ZERO {
                        let w = match (direct, self.lights.emitter_index(hit.tri)) {
                            (true, Some(k)) => {
                                let p_b = n.dot(dir) / std::f32::consts::PI;
                                let p_l = self.lights.pdf_solid_angle(g, k, p, hit.p, hit.n);
                                p_b / (p_b + p_l)
                            }
                            _ => 1.0,
                        };
                        l += le * w;
                    }
                }
                let albedo = self.scene.albedo_at(m, uv0).0;
                l += albedo * self.outgoing_diffuse(&hit, albedo, rng, depth);
                (t * l, false)
            }
        };
        (l + glow, back)
    }

    /// H/π at a diffuse hit reached after `depth` bounces: the lightmap in
    /// final-pass mode, else a recursive estimate under Russian roulette
    /// (survival probability max ρ, clamped to [0.05, 0.95]).
    fn outgoing_diffuse(&self, hit: &Landing, albedo: Vec3, rng: &mut Stream, depth: u32) -> Vec3 {
        if let Some(lm) = &self.lightmaps {
            let g = self.geometry;
            return lm.at(g.page[hit.tri as usize], g.uv_lm_at(hit.tri, hit.u, hit.v));
        }
        if depth >= self.max_depth || albedo.max_element() <= 0.0 {
            return Vec3::ZERO;
        }
        let mut scale = 1.0;
        if depth >= self.rr_depth {
            let q = albedo.max_element().clamp(0.05, 0.95);
            if rng.next_f32() >= q {
                return Vec3::ZERO;
            }
            scale = 1.0 / q;
        }
        self.incident(hit.p, hit.n, rng, depth).0 * scale
    }

    /// Unbiased estimate of H/π = (1/π) ∫ L_i cos θ dω at diffuse point `p`
    /// whose normal `n` faces the light, after `depth` diffuse bounces.
    /// Returns (estimate, the hemisphere ray hit a back face).
    pub fn incident(&self, p: Vec3, n: Vec3, rng: &mut Stream, depth: u32) -> (Vec3, bool) {
        let g = self.geometry;
        let pi = std::f32::consts::PI;
        let origin = offset_ray_origin(p, n);
        let mut h = Vec3::ZERO;
        for light in &self.lights.punctual {
            if depth == 0 && self.skip_mixed_direct && light.mode.is_mixed() {
                continue;
            }
            if let Some((value, dir, dist)) = punctual_irradiance(light, p, n) {
                let (dir, dist) = if light.has_extent() {
                    // One point of a sphere or sun disk.
                    extent_sample(light, dir, dist, rng.next_vec2())
                } else {
                    (dir, dist)
                };
                if n.dot(dir) > 0.0 && punctual_unoccluded(self.rays, origin, dir, dist) {
                    h += value;
                }
            }
        }
        // Light sample, balance heuristic against the hemisphere sample.
        if let Some(ls) = self.lights.sample(g, rng.next_vec2()) {
            let d = ls.point - p;
            let dist2 = d.length_squared();
            let dist = dist2.sqrt();
            let dir = d / dist;
            let cos_p = n.dot(dir);
            let cos_q = ls.normal.dot(-dir);
            if cos_p > 0.0 && cos_q > 0.0 && {
                let (o, sd, len) = shadow_ray(p, n, ls.point, ls.normal);
                self.rays.unoccluded(o, sd, len)
            } {
                let le = self
                    .scene
                    .emission_at(g.material[ls.tri as usize], g.uv0_at(ls.tri, ls.u, ls.v));
                let p_l = ls.pdf_area * dist2 / cos_q;
                let p_b = cos_p / pi;
                h += le * (cos_p / pi) / (p_l + p_b);
            }
        } else {
            // Keep the stream's layout independent of the scene's emitters.
            rng.next_vec2();
        }
        // A sky map's light sample, balance heuristic against the
        // hemisphere sample (drawn only with a map: a uniform sky's stream
        // is as it was).
        if let Some(map) = self.lights.sky.map().filter(|m| !m.is_black()) {
            let (dir, p_l, l) = map.sample(rng.next_vec2());
            let cos_p = n.dot(dir);
            if p_l > 0.0 && cos_p > 0.0 && self.rays.unoccluded(origin, dir, f32::INFINITY) {
                let p_b = cos_p / pi;
                h += l * (cos_p / pi) / (p_l + p_b);
            }
        }
        // Hemisphere sample: with pdf cos θ / π, L cos θ / (π pdf) = L.
        let dir = to_world(cosine_hemisphere(rng.next_vec2()), n);
        let (l, back) = self.gathered(p, n, dir, rng, depth + 1);
        (h + l, back)
    }

    /// Radiance arriving at the camera along −`dir` from `origin`.
    pub fn radiance(&self, origin: Vec3, dir: Vec3, rng: &mut Stream) -> Vec3 {
        let g = self.geometry;
        let (reach, glow) = self.reach(origin, dir, rng, None);
        glow + match reach {
            Reach::Sky(t, d, _) => t * self.lights.sky.radiance(d),
            Reach::Back | Reach::Nothing => Vec3::ZERO,
            Reach::Diffuse(hit, t, _) => {
                let m = g.material[hit.tri as usize];
                let uv0 = g.uv0_at(hit.tri, hit.u, hit.v);
                let mut l = Vec3::ZERO;
                if hit.front {
                    l += self.scene.emission_at(m, uv0);
                }
                let albedo = self.scene.albedo_at(m, uv0).0;
                if albedo.max_element() > 0.0 {
                    l += albedo * self.incident(hit.p, hit.n, rng, 0).0;
                }
                t * l
            }
        }
    }
}

/// Unpolarised Fresnel reflectance of a smooth dielectric for incidence
/// cosine `cos_i`, transmission cosine `cos_t` and relative index
/// `eta` = n_i / n_t.
fn fresnel_dielectric(cos_i: f32, cos_t: f32, eta: f32) -> f32 {
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (rs * rs + rp * rp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_at_normal_incidence() {
        // ((1 − 1.5) / (1 + 1.5))² = 0.04.
        let f = fresnel_dielectric(1.0, 1.0, 1.0 / 1.5);
        assert!((f - 0.04).abs() < 1e-6, "{f}");
        // Grazing incidence reflects everything.
        assert!(fresnel_dielectric(1e-6, 0.75, 1.0 / 1.5) > 0.999);
    }

    #[test]
    fn lightmap_lookup_is_bilinear_between_texel_centres() {
        let pages = vec![vec![Vec3::ZERO, Vec3::ONE, Vec3::ZERO, Vec3::ONE]];
        let lm = LightmapLookup {
            width: 2,
            height: 2,
            pages: &pages,
        };
        assert_eq!(lm.at(0, Vec2::new(0.5, 0.5)), Vec3::ZERO);
        assert_eq!(lm.at(0, Vec2::new(1.5, 1.5)), Vec3::ONE);
        assert!((lm.at(0, Vec2::new(1.0, 0.7)).x - 0.5).abs() < 1e-6);
        // Clamped outside the page; missing pages are black.
        assert_eq!(lm.at(0, Vec2::new(9.0, 0.5)), Vec3::ONE);
        assert_eq!(lm.at(3, Vec2::new(0.5, 0.5)), Vec3::ZERO);
    }
}
