//! Bidirectional path tracing (Veach & Guibas 1995; Veach's thesis 1997,
//! ch. 10), laid out as in PBRT (Pharr, Jakob & Humphreys, 3rd ed., §16.3):
//! a camera subpath and a light subpath, every connection (s light
//! vertices, t camera vertices) evaluated, each weighted by the balance
//! heuristic computed from forward and reverse area-measure pdfs.
//!
//! Scope: Lambertian surfaces, emissive triangles and point/spot lights as
//! the finite lights that start light subpaths. Every strategy with t ≥ 1
//! is used: t = 1 connects light subpath vertices to the pinhole and splats
//! them onto the film (light tracing), which is what resolves small bright
//! spots lit by a small light. Light that only one strategy can
//! carry keeps weight 1: the sky (camera paths that escape) and directional
//! lights (a shadow ray from every camera vertex). Scenes with mirrors or
//! glass are rendered by the unidirectional tracer instead (see
//! [`supports`]).

use super::Tracer;
use crate::light::lights::punctual_irradiance;
use crate::scene::{LightKind, Specular};
use crate::util::sampling::{cosine_hemisphere, offset_ray_origin, shadow_ray, to_world, Stream};
use glam::Vec3;
use std::f32::consts::PI;

/// Longest path (in bounces) either subpath builds.
const MAX_DEPTH: usize = 16;
/// Russian roulette starts after this many bounces of a subpath.
const RR_DEPTH: usize = 3;

/// True when the scene is within BDPT's scope (no perfectly specular material).
pub fn supports(tracer: &Tracer) -> bool {
    tracer
        .scene
        .materials
        .iter()
        .all(|m| m.specular == Specular::None)
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    /// The pinhole: viewing direction and film area at unit distance.
    Camera { forward: Vec3, film_area: f32 },
    /// A point on emitter `k` (index in `Lights::emitters`).
    AreaLight { k: usize, tri: u32, le: Vec3 },
    /// Punctual light `i` (point or spot).
    PointLight { i: usize },
    Surface {
        tri: u32,
        albedo: Vec3,
        emission: Vec3,
    },
}

#[derive(Clone, Copy, Debug)]
struct Vertex {
    kind: Kind,
    p: Vec3,
    /// Surfaces: geometric normal on the side the subpath arrived from;
    /// area lights: the emitting front; zero for points.
    n: Vec3,
    beta: Vec3,
    pdf_fwd: f32,
    pdf_rev: f32,
}

impl Vertex {
    fn has_normal(&self) -> bool {
        self.n != Vec3::ZERO
    }

    /// Solid-angle density `pdf` at `self` towards `next`, as an area density at `next`.
    fn convert(&self, pdf: f32, next: &Vertex) -> f32 {
        let w = next.p - self.p;
        let d2 = w.length_squared();
        if d2 == 0.0 {
            return 0.0;
        }
        let mut pdf = pdf / d2;
        if next.has_normal() {
            pdf *= next.n.dot(w / d2.sqrt()).abs();
        }
        pdf
    }

    /// Lambertian BRDF value for leaving towards `next` (zero on the far side).
    fn f(&self, next: &Vertex) -> Vec3 {
        match self.kind {
            Kind::Surface { albedo, .. } if self.n.dot(next.p - self.p) > 0.0 => albedo / PI,
            _ => Vec3::ZERO,
        }
    }

    /// Area density at `next` of sampling `next` from `self` (a surface
    /// samples cos θ / π; a light emits by [`Vertex::pdf_light`]).
    fn pdf(&self, next: &Vertex) -> f32 {
        match self.kind {
            Kind::Surface { .. } => {
                let w = (next.p - self.p).normalize_or_zero();
                let cos = self.n.dot(w);
                if cos <= 0.0 {
                    0.0
                } else {
                    self.convert(cos / PI, next)
                }
            }
            Kind::AreaLight { .. } | Kind::PointLight { .. } => self.pdf_light(next),
            Kind::Camera { forward, film_area } => {
                let w = (next.p - self.p).normalize_or_zero();
                let cos = forward.dot(w);
                if cos <= 0.0 {
                    0.0
                } else {
                    // Uniform over the film: 1 / (A cos³θ) per steradian.
                    self.convert(1.0 / (film_area * cos * cos * cos), next)
                }
            }
        }
    }

    /// Area density at `next` of a light at `self` emitting towards it:
    /// cosine-weighted from an emitter, uniform over the sphere from a point.
    fn pdf_light(&self, next: &Vertex) -> f32 {
        let w = (next.p - self.p).normalize_or_zero();
        let pdf_dir = match self.kind {
            Kind::PointLight { .. } => 1.0 / (4.0 * PI),
            _ => self.n.dot(w).max(0.0) / PI,
        };
        self.convert(pdf_dir, next)
    }
}

/// The discrete choice between the finite lights, by power: all emitter
/// triangles as one group (then by their own CDF), and each point/spot light.
struct LightChoice {
    area: f32,
    points: Vec<(usize, f32)>,
}

impl LightChoice {
    fn new(tracer: &Tracer) -> LightChoice {
        let l = &tracer.lights;
        let area_power = PI * l.cdf.last().copied().unwrap_or(0.0);
        let points: Vec<(usize, f32)> = l
            .punctual
            .iter()
            .enumerate()
            .filter(|(_, p)| p.kind != LightKind::Directional)
            .map(|(i, p)| (i, 4.0 * PI * p.intensity.element_sum()))
            .collect();
        let total = area_power + points.iter().map(|p| p.1).sum::<f32>();
        if total <= 0.0 {
            return LightChoice {
                area: 0.0,
                points: Vec::new(),
            };
        }
        LightChoice {
            area: area_power / total,
            points: points.into_iter().map(|(i, p)| (i, p / total)).collect(),
        }
    }

    fn is_empty(&self) -> bool {
        self.area <= 0.0 && self.points.is_empty()
    }

    fn point_probability(&self, i: usize) -> f32 {
        self.points.iter().find(|p| p.0 == i).map_or(0.0, |p| p.1)
    }

    /// Area density of the light sampler choosing emitter point `v`.
    fn pdf_origin(&self, tracer: &Tracer, v: &Vertex) -> f32 {
        match v.kind {
            Kind::AreaLight { k, tri, .. } => {
                self.area * tracer.lights.pick(k) / tracer.geometry.area[tri as usize]
            }
            Kind::Surface { tri, .. } => match tracer.lights.emitter_index(tri) {
                Some(k) => self.area * tracer.lights.pick(k) / tracer.geometry.area[tri as usize],
                None => 0.0,
            },
            Kind::PointLight { i } => self.point_probability(i),
            Kind::Camera { .. } => 0.0,
        }
    }

    /// Samples a light vertex (position only).
    fn sample(&self, tracer: &Tracer, rng: &mut Stream) -> Option<Vertex> {
        let u = rng.next_f32();
        let uv = rng.next_vec2();
        if u < self.area {
            let ls = tracer.lights.sample(tracer.geometry, uv)?;
            let le = tracer.scene.emission_at(
                tracer.geometry.material[ls.tri as usize],
                tracer.geometry.uv0_at(ls.tri, ls.u, ls.v),
            );
            let pdf = self.area * ls.pdf_area;
            return Some(Vertex {
                kind: Kind::AreaLight {
                    k: ls.k,
                    tri: ls.tri,
                    le,
                },
                p: ls.point,
                n: ls.normal,
                beta: le / pdf,
                pdf_fwd: pdf,
                pdf_rev: 0.0,
            });
        }
        let mut acc = self.area;
        for &(i, p) in &self.points {
            acc += p;
            if u < acc || i == self.points.last().map_or(i, |l| l.0) {
                let light = &tracer.lights.punctual[i];
                return Some(Vertex {
                    kind: Kind::PointLight { i },
                    p: light.position,
                    n: Vec3::ZERO,
                    beta: Vec3::ONE / p,
                    pdf_fwd: p,
                    pdf_rev: 0.0,
                });
            }
        }
        None
    }
}

/// Radiant intensity of punctual light `i` towards unit `w`, with the
/// spot cone and the range window at distance `dist`.
fn point_intensity(tracer: &Tracer, i: usize, w: Vec3, dist: f32) -> Vec3 {
    let light = &tracer.lights.punctual[i];
    // punctual_irradiance gives I cos θ_r / (π d²) for a receiver facing the
    // light head-on (cos θ_r = 1): undo the d² and π to keep the window and
    // the cone in one place.
    let receiver = light.position + w * dist;
    match punctual_irradiance(light, receiver, -w) {
        Some((value, _, _)) => value * (PI * dist * dist),
        None => Vec3::ZERO,
    }
}

/// Extends `path` by a random walk from its last vertex along `dir`
/// (sampled there with solid-angle density `pdf_dir`), Lambertian bounces
/// with Russian roulette. Returns the sky radiance × throughput seen by a
/// camera walk that escapes.
#[allow(clippy::too_many_arguments)]
fn walk(
    tracer: &Tracer,
    path: &mut Vec<Vertex>,
    mut origin: Vec3,
    mut dir: Vec3,
    mut beta: Vec3,
    mut pdf_dir: f32,
    rng: &mut Stream,
    max_vertices: usize,
    camera: bool,
) -> Vec3 {
    let g = tracer.geometry;
    let mut escaped = Vec3::ZERO;
    while path.len() < max_vertices {
        let Some(hit) = tracer.rays.closest_hit(origin, dir, f32::INFINITY) else {
            if camera {
                escaped = beta * tracer.lights.sky.radiance(dir);
            }
            break;
        };
        let tri = hit.tri as usize;
        let m = g.material[tri];
        let material = &tracer.scene.materials[m as usize];
        let ng = g.ng_ws[tri];
        let front = ng.dot(dir) < 0.0;
        if !front && !material.double_sided {
            break;
        }
        let uv0 = g.uv0_at(hit.tri, hit.u, hit.v);
        let mut v = Vertex {
            kind: Kind::Surface {
                tri: hit.tri,
                albedo: tracer.scene.albedo_at(m, uv0).0,
                emission: if front {
                    tracer.scene.emission_at(m, uv0)
                } else {
                    Vec3::ZERO
                },
            },
            p: g.point(hit.tri, hit.u, hit.v),
            n: if front { ng } else { -ng },
            beta,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
        };
        let prev = *path.last().expect("a subpath starts with its endpoint");
        v.pdf_fwd = prev.convert(pdf_dir, &v);
        // A point light's range window acts on the first segment.
        if let Kind::PointLight { i } = prev.kind {
            if tracer.lights.punctual[i].range.is_some() {
                let d = (v.p - prev.p).length();
                let full = point_intensity(tracer, i, dir, d);
                let bare = point_intensity(tracer, i, dir, 1e-3);
                let scale = (full / bare.max(Vec3::splat(1e-30))).max_element();
                v.beta *= scale.clamp(0.0, 1.0);
                beta = v.beta;
            }
        }
        path.push(v);
        if path.len() >= max_vertices {
            break;
        }
        let Kind::Surface { albedo, .. } = v.kind else {
            break;
        };
        let bounces = path.len() - 1;
        // Lambertian: f cos / pdf = ρ.
        beta *= albedo;
        if bounces >= RR_DEPTH {
            let q = albedo.max_element().clamp(0.05, 0.95);
            if rng.next_f32() >= q {
                break;
            }
            beta /= q;
        }
        if beta.max_element() <= 0.0 {
            break;
        }
        let new_dir = to_world(cosine_hemisphere(rng.next_vec2()), v.n);
        pdf_dir = v.n.dot(new_dir) / PI;
        // Reverse density at the previous vertex: from v back along −dir.
        let pdf_rev_dir = v.n.dot(-dir).max(0.0) / PI;
        let last = path.len() - 1;
        let rev = v.convert(pdf_rev_dir, &path[last - 1]);
        path[last - 1].pdf_rev = rev;
        origin = offset_ray_origin(v.p, v.n);
        dir = new_dir;
    }
    escaped
}

fn visible(tracer: &Tracer, a: &Vertex, b: &Vertex) -> bool {
    let d = b.p - a.p;
    let dist = d.length();
    if dist <= 0.0 {
        return false;
    }
    let (origin, dir, len) = match (a.has_normal(), b.has_normal()) {
        (true, true) => shadow_ray(a.p, a.n, b.p, b.n),
        // A point light: nothing to avoid at its end.
        (true, false) => {
            let o = offset_ray_origin(a.p, if a.n.dot(d) > 0.0 { a.n } else { -a.n });
            let e = b.p - o;
            (o, e.normalize_or_zero(), e.length())
        }
        _ => (a.p, d / dist, dist),
    };
    tracer.rays.unoccluded(origin, dir, len)
}

/// Balance-heuristic weight of strategy (s, t) for the connected path
/// (PBRT's `MISWeight`, the t = 1 strategies left out).
fn mis_weight(
    tracer: &Tracer,
    choice: &LightChoice,
    light: &[Vertex],
    camera: &[Vertex],
    sampled: Option<Vertex>,
    s: usize,
    t: usize,
) -> f32 {
    if s + t == 2 {
        return 1.0;
    }
    // The connection's end vertices; for s = 1 the fresh light sample.
    let pt = camera[t - 1];
    let qs = match s {
        0 => None,
        1 => Some(sampled.expect("s = 1 uses a fresh light sample")),
        _ => Some(light[s - 1]),
    };
    // Reverse densities at the connection (the rest are the walks' own);
    // read through overrides instead of copying the subpaths.
    let pt_rev = match qs {
        Some(q) => q.pdf(&pt),
        None => choice.pdf_origin(tracer, &pt),
    };
    let ptm_rev = match qs {
        Some(_) if t >= 2 => pt.pdf(&camera[t - 2]),
        // pt is an emitter point emitting towards y_{t−2}.
        None if t >= 2 => Vertex {
            kind: Kind::AreaLight {
                k: 0,
                tri: 0,
                le: Vec3::ZERO,
            },
            ..pt
        }
        .pdf_light(&camera[t - 2]),
        _ => 0.0,
    };
    let qs_rev = qs.map_or(0.0, |q| pt.pdf(&q));
    let qsm_rev = match qs {
        Some(q) if s >= 2 => q.pdf(&light[s - 2]),
        _ => 0.0,
    };
    let light_at = |i: usize| if s == 1 { qs.expect("s = 1") } else { light[i] };
    let remap = |f: f32| if f != 0.0 { f } else { 1.0 };
    let mut sum = 0.0f32;
    let mut ri = 1.0f32;
    // Shorter camera subpaths, down to t = 1 (light tracing).
    for i in (1..t).rev() {
        let rev = if i == t - 1 {
            pt_rev
        } else if i + 2 == t {
            ptm_rev
        } else {
            camera[i].pdf_rev
        };
        ri *= remap(rev) / remap(camera[i].pdf_fwd);
        sum += ri;
    }
    ri = 1.0;
    for i in (0..s).rev() {
        let v = light_at(i);
        let rev = if i == s - 1 {
            qs_rev
        } else if i + 2 == s {
            qsm_rev
        } else {
            v.pdf_rev
        };
        ri *= remap(rev) / remap(v.pdf_fwd);
        // A point light cannot be hit: its s' = 0 strategy does not exist.
        let delta_light = i == 0 && matches!(light_at(0).kind, Kind::PointLight { .. });
        if !delta_light {
            sum += ri;
        }
    }
    1.0 / (1.0 + sum)
}

/// A tracer prepared for BDPT (the light choice computed once).
pub struct Bdpt<'t, 'a> {
    tracer: &'t Tracer<'a>,
    choice: LightChoice,
}

impl<'t, 'a> Bdpt<'t, 'a> {
    /// Prepares `tracer`.
    pub fn new(tracer: &'t Tracer<'a>) -> Self {
        Bdpt {
            tracer,
            choice: LightChoice::new(tracer),
        }
    }

    /// Radiance arriving at the camera of `view` along −`dir`, plus the
    /// light-tracing (t = 1) contributions, pushed to `splats` as (film
    /// point in [−1, 1]², value): each is to be added to the pixel it lands
    /// in and divided by the samples per pixel (PBRT's splat film).
    pub fn radiance(
        &self,
        view: &super::view::View,
        aspect: f32,
        dir: Vec3,
        rng: &mut Stream,
        splats: &mut Vec<(glam::Vec2, Vec3)>,
    ) -> Vec3 {
        let (tracer, choice) = (self.tracer, &self.choice);
        let eye = view.eye;
        let film_area = 4.0 * view.tan_half_y * view.tan_half_y * aspect;
        let cos0 = view.forward.dot(dir);
        // Camera subpath: the eye, then the walk (pinhole: β = 1 per sample).
        let mut camera = vec![Vertex {
            kind: Kind::Camera {
                forward: view.forward,
                film_area,
            },
            p: eye,
            n: Vec3::ZERO,
            beta: Vec3::ONE,
            pdf_fwd: 1.0,
            pdf_rev: 0.0,
        }];
        let sky = walk(
            tracer,
            &mut camera,
            eye,
            dir,
            Vec3::ONE,
            1.0 / (film_area * cos0 * cos0 * cos0),
            rng,
            MAX_DEPTH + 2,
            true,
        );
        let mut l = sky;
        // Light subpath from a finite light.
        let light = self.light_subpath(rng);

        // t = 1: light subpath vertices seen by the camera, splatted.
        self.splat_light_vertices((view, aspect, film_area), &light, &camera, splats);

        for t in 2..=camera.len() {
            let pt = camera[t - 1];
            let Kind::Surface { albedo, .. } = pt.kind else {
                continue;
            };
            // Directional lights: one shadow ray, the only strategy (weight 1).
            for light in &tracer.lights.punctual {
                if light.kind == LightKind::Directional {
                    if let Some((value, to, _)) = punctual_irradiance(light, pt.p, pt.n) {
                        if tracer
                            .rays
                            .unoccluded(offset_ray_origin(pt.p, pt.n), to, f32::INFINITY)
                        {
                            l += pt.beta * albedo * value;
                        }
                    }
                }
            }
            for s in 0..=light.len() {
                if s + t - 2 > MAX_DEPTH {
                    break;
                }
                let Some((contribution, sampled)) = self.strategy(&pt, &light, s, rng) else {
                    continue;
                };
                if contribution.max_element() <= 0.0 {
                    continue;
                }
                l += contribution * mis_weight(tracer, choice, &light, &camera, sampled, s, t);
            }
        }
        l
    }

    /// A light subpath from a finite light: its first vertex chosen by
    /// power, then a cosine-weighted (area light) or uniform (point light)
    /// direction and the walk; empty where there is no finite light.
    fn light_subpath(&self, rng: &mut Stream) -> Vec<Vertex> {
        let (tracer, choice) = (self.tracer, &self.choice);
        let mut light: Vec<Vertex> = Vec::new();
        if !choice.is_empty() {
            if let Some(z0) = choice.sample(tracer, rng) {
                let u = rng.next_vec2();
                let (dir, pdf_dir, beta) = match z0.kind {
                    Kind::AreaLight { le, .. } => {
                        let d = to_world(cosine_hemisphere(u), z0.n);
                        // Le cos / (p_A · cos/π) = Le π / p_A.
                        (d, z0.n.dot(d) / PI, le * PI / z0.pdf_fwd)
                    }
                    Kind::PointLight { i } => {
                        let z = 1.0 - 2.0 * u.x;
                        let r = (1.0 - z * z).max(0.0).sqrt();
                        let phi = 2.0 * PI * u.y;
                        let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                        let intensity = point_intensity(tracer, i, d, 1e-3);
                        (d, 1.0 / (4.0 * PI), intensity * (4.0 * PI) / z0.pdf_fwd)
                    }
                    _ => unreachable!("light samples are lights"),
                };
                light.push(z0);
                if beta.max_element() > 0.0 && pdf_dir > 0.0 {
                    let origin = if z0.has_normal() {
                        offset_ray_origin(z0.p, z0.n)
                    } else {
                        z0.p
                    };
                    walk(
                        tracer,
                        &mut light,
                        origin,
                        dir,
                        beta,
                        pdf_dir,
                        rng,
                        MAX_DEPTH + 1,
                        false,
                    );
                }
            }
        }
        light
    }

    /// The t = 1 strategies (light tracing): every light subpath vertex
    /// that the camera of `view` sees, splatted to its film point with
    /// its MIS weight.
    fn splat_light_vertices(
        &self,
        (view, aspect, film_area): (&super::view::View, f32, f32),
        light: &[Vertex],
        camera: &[Vertex],
        splats: &mut Vec<(glam::Vec2, Vec3)>,
    ) {
        let (tracer, choice) = (self.tracer, &self.choice);
        let eye = view.eye;
        let cam = camera[0];
        for s in 2..=light.len().min(MAX_DEPTH + 1) {
            let qs = light[s - 1];
            let d = eye - qs.p;
            let dist2 = d.length_squared();
            let w = d / dist2.sqrt();
            let f_q = qs.f(&cam);
            let cos_cam = view.forward.dot(-w);
            if f_q == Vec3::ZERO || cos_cam <= 0.0 {
                continue;
            }
            let Some(film) = view.project(qs.p, aspect) else {
                continue;
            };
            if !visible(tracer, &qs, &cam) {
                continue;
            }
            // β f |cos_q| cosθ / d² × W_e, W_e = 1 / (A cos⁴θ).
            let we = 1.0 / (film_area * cos_cam.powi(4));
            let c = qs.beta * f_q * (qs.n.dot(w).abs() * cos_cam / dist2) * we;
            if c.max_element() > 0.0 {
                let weight = mis_weight(tracer, choice, light, camera, None, s, 1);
                splats.push((film, c * weight));
            }
        }
    }

    /// Strategy (s, t) at camera vertex `pt` (t ≥ 2): the emission `pt`
    /// sees (s = 0), a new light sample connected to it (s = 1, returned
    /// as the vertex the MIS weight needs) or the connection to light
    /// subpath vertex s; None where it brings nothing or is occluded.
    fn strategy(
        &self,
        pt: &Vertex,
        light: &[Vertex],
        s: usize,
        rng: &mut Stream,
    ) -> Option<(Vec3, Option<Vertex>)> {
        let (tracer, choice) = (self.tracer, &self.choice);
        let Kind::Surface {
            albedo, emission, ..
        } = pt.kind
        else {
            return None;
        };
        let (contribution, sampled) = match s {
            0 => {
                if emission == Vec3::ZERO
                    || tracer
                        .lights
                        .emitter_index(match pt.kind {
                            Kind::Surface { tri, .. } => tri,
                            _ => u32::MAX,
                        })
                        .is_none()
                {
                    return None;
                }
                (pt.beta * emission, None)
            }
            1 => {
                let mut q = choice.sample(tracer, rng)?;
                let d = pt.p - q.p;
                let dist2 = d.length_squared();
                let w = d / dist2.sqrt();
                let emitted = match q.kind {
                    Kind::AreaLight { le, .. } => {
                        if q.n.dot(w) <= 0.0 {
                            return None;
                        }
                        le * q.n.dot(w)
                    }
                    Kind::PointLight { i } => point_intensity(tracer, i, w, dist2.sqrt()),
                    _ => return None,
                };
                let cos_pt = pt.n.dot(-w);
                if cos_pt <= 0.0 || emitted.max_element() <= 0.0 || !visible(tracer, pt, &q) {
                    return None;
                }
                // pt.β f Le cos_q cos_pt / (d² p_A)  (point: I cos_pt / (d² p)).
                let c = pt.beta * (albedo / PI) * emitted * cos_pt / (dist2 * q.pdf_fwd);
                q.beta = Vec3::ONE;
                (c, Some(q))
            }
            _ => {
                let qs = light[s - 1];
                let f_q = qs.f(pt);
                let f_p = pt.f(&qs);
                if f_q == Vec3::ZERO || f_p == Vec3::ZERO {
                    return None;
                }
                let d = qs.p - pt.p;
                let dist2 = d.length_squared();
                let w = d / dist2.sqrt();
                let g = pt.n.dot(w).abs() * qs.n.dot(w).abs() / dist2;
                if !visible(tracer, pt, &qs) {
                    return None;
                }
                (qs.beta * f_q * g * f_p * pt.beta, None)
            }
        };
        Some((contribution, sampled))
    }
}
