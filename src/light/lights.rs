//! The light-sampling library every stage that computes light shares: the
//! scene's lights gathered for sampling ([`Lights`]), punctual lights'
//! irradiance and shadow tests, emitter and sky samples, the multiple
//! importance sampling weights between light samples and cosine rays
//! ([`Mis`]; Veach 1997, §9.2), and what a ray that hits a surface or
//! escapes to the sky brings back.

use crate::config::EmitterSampling;
use crate::layout::geometry::Geometry;
use crate::light::sky::Sky;
use crate::raycast::RayCaster;
use crate::scene::{Light, LightKind, LightMode, Scene};
use crate::util::sampling::{offset_ray_origin, stratified, to_world, Stream};
use glam::{Vec2, Vec3};

/// Everything that emits.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// Emissive triangles (global ids).
    pub emitters: Vec<u32>,
    /// Cumulative power of `emitters` (unnormalised), for sampling by power.
    pub cdf: Vec<f32>,
    /// Punctual lights.
    pub punctual: Vec<Light>,
    /// What rays that leave the scene see: a uniform colour, or a sky map
    /// (importance-sampled; see [`sky_light`]).
    pub sky: Sky,
    /// A sky map's light samples per texel (or probe), for its MIS
    /// weights ([`escaped`]); set by the caller (`config.sky_samples`).
    pub sky_samples: u32,
    /// One light layer's share of each light (`None`: all of it); see
    /// [`Mask`].
    pub mask: Option<Mask>,
}

/// One light layer's share of every light ([`crate::scene::layers`]):
/// per punctual light (by its index in [`Lights::punctual`]), per material
/// (its emission) and of the sky, 1 or 0. It scales what each light
/// contributes where that contribution is read, and nothing else: the
/// lights are sampled, and every ray is cast, as without it, so the
/// layers' bakes share their random numbers and sum to the whole bake.
#[derive(Clone, Debug, Default)]
pub struct Mask {
    /// Per punctual light.
    pub punctual: Vec<f32>,
    /// Per material.
    pub material: Vec<f32>,
    /// The sky's.
    pub sky: f32,
}

impl Mask {
    /// Layer `k` of `layers` (over `scene`, whose baked lights are
    /// [`Lights::punctual`], in order).
    pub fn of_layer(layers: &crate::scene::layers::Layers, scene: &Scene, k: usize) -> Mask {
        let share = |x: &Option<usize>| if *x == Some(k) { 1.0 } else { 0.0 };
        Mask {
            punctual: (scene.lights.iter().zip(&layers.light))
                .filter(|(l, _)| l.mode != LightMode::Realtime)
                .map(|(_, x)| share(x))
                .collect(),
            material: layers.material.iter().map(share).collect(),
            sky: share(&layers.sky),
        }
    }
}

impl Lights {
    /// Collects the emissive triangles of `geometry` whose material is
    /// flagged in `sampled`, the scene's baked lights (every mode but
    /// [`LightMode::Realtime`]) and the sky.
    pub fn new(
        scene: &Scene,
        geometry: &Geometry,
        sampled: &[bool],
        sky: impl Into<Sky>,
    ) -> Lights {
        let mut l = Lights {
            punctual: scene
                .lights
                .iter()
                .filter(|l| l.mode != LightMode::Realtime)
                .cloned()
                .collect(),
            sky: sky.into(),
            ..Default::default()
        };
        let mut total = 0.0f32;
        // A node that casts no shadows is not in the ray caster: no ray can
        // meet its emitters, so they are not lights either.
        let seen = |t: usize| {
            scene
                .instances
                .get(geometry.instance[t] as usize)
                .is_none_or(|i| i.cast_shadows)
        };
        for t in 0..geometry.len() {
            let m = &scene.materials[geometry.material[t] as usize];
            if m.is_emissive() && sampled[geometry.material[t] as usize] && seen(t) {
                total += geometry.area[t] * m.emission.element_sum();
                l.emitters.push(t as u32);
                l.cdf.push(total);
            }
        }
        l
    }

    fn total_power(&self) -> f32 {
        self.cdf.last().copied().unwrap_or(0.0)
    }

    /// Probability of picking emitter triangle `tri` (by its index in `emitters`).
    fn pick_probability(&self, k: usize) -> f32 {
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        (self.cdf[k] - lo) / self.total_power()
    }

    /// A point on the emitters for the unit-square sample `u`: the first
    /// coordinate picks an emitter triangle through the power CDF, its
    /// remainder and the second coordinate a uniform point on it
    /// (square-root parameterisation), so a stratified `u` stays stratified
    /// over the whole emitting surface. None when there are no emitters.
    pub fn sample(&self, g: &Geometry, u: Vec2) -> Option<EmitterSample> {
        if self.emitters.is_empty() {
            return None;
        }
        let total = self.total_power();
        let x = u.x * total;
        let k = self
            .cdf
            .partition_point(|&c| c <= x)
            .min(self.emitters.len() - 1);
        let tri = self.emitters[k];
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let r1 = ((x - lo) / (self.cdf[k] - lo)).clamp(0.0, 1.0);
        let su = r1.sqrt();
        let (u, v) = (su * (1.0 - u.y), su * u.y);
        Some(EmitterSample {
            k,
            tri,
            u,
            v,
            point: g.point(tri, u, v),
            normal: g.ng_ws[tri as usize],
            pdf_area: self.pick_probability(k) / g.area[tri as usize],
        })
    }

    /// Index in [`Lights::emitters`] of emitter triangle `tri`, if sampled.
    pub fn emitter_index(&self, tri: u32) -> Option<usize> {
        self.emitters.binary_search(&tri).ok()
    }

    /// Solid-angle pdf with which [`Lights::sample`] picks the direction from
    /// `p` to point `q` (normal `nq`) of emitter `k`: p_A · d² / cos θ_q.
    pub fn pdf_solid_angle(&self, g: &Geometry, k: usize, p: Vec3, q: Vec3, nq: Vec3) -> f32 {
        let tri = self.emitters[k] as usize;
        let d = q - p;
        let dist2 = d.length_squared();
        let cos_q = nq.dot(-d / dist2.sqrt());
        if cos_q <= 0.0 {
            return 0.0;
        }
        self.pick_probability(k) / g.area[tri] * dist2 / cos_q
    }

    /// Probability of picking emitter `k` (index in [`Lights::emitters`]).
    pub fn pick(&self, k: usize) -> f32 {
        self.pick_probability(k)
    }

    /// The sky map's MIS counts: [`Lights::sky_samples`] light samples
    /// against `mis`'s hemisphere rays.
    pub fn sky_mis(&self, mis: Mis) -> Mis {
        Mis {
            light: self.sky_samples,
            hemisphere: mis.hemisphere,
        }
    }

    /// These lights with `mask` applied ([`Mask`]).
    pub fn masked(&self, mask: Mask) -> Lights {
        Lights {
            mask: Some(mask),
            ..self.clone()
        }
    }

    /// The layer's share of punctual light `i` ([`Lights::mask`]).
    #[inline(always)]
    pub fn punctual_weight(&self, i: usize) -> f32 {
        self.mask.as_ref().map_or(1.0, |m| m.punctual[i])
    }

    /// The layer's share of material `m`'s emission.
    #[inline(always)]
    pub fn emission_weight(&self, m: u32) -> f32 {
        self.mask.as_ref().map_or(1.0, |k| k.material[m as usize])
    }

    /// The layer's share of the sky.
    #[inline(always)]
    pub fn sky_weight(&self) -> f32 {
        self.mask.as_ref().map_or(1.0, |m| m.sky)
    }

    /// True when there are local lights: emitters, or point or spot
    /// lights ([`Light::is_local`]).
    pub fn has_local(&self) -> bool {
        !self.emitters.is_empty() || self.punctual.iter().any(|l| l.is_local())
    }

    /// True when nothing emits.
    pub fn is_empty(&self) -> bool {
        self.emitters.is_empty() && self.punctual.is_empty() && self.sky.is_black()
    }
}

/// A point sampled on the emitters by [`Lights::sample`].
#[derive(Clone, Copy, Debug)]
pub struct EmitterSample {
    /// Index in [`Lights::emitters`].
    pub k: usize,
    /// Global triangle id.
    pub tri: u32,
    /// Barycentrics (weights of corners 1 and 2).
    pub u: f32,
    /// See `u`.
    pub v: f32,
    /// The point (world).
    pub point: Vec3,
    /// The emitter's front normal.
    pub normal: Vec3,
    /// Area-measure pdf of the point (pick probability / triangle area).
    pub pdf_area: f32,
}

/// Irradiance / π at `p` (normal `n`) from one punctual light, unshadowed,
/// and the direction and distance to test for shadow.
pub fn punctual_irradiance(light: &Light, p: Vec3, n: Vec3) -> Option<(Vec3, Vec3, f32)> {
    let (e, to_light, dist) = punctual_incident(light, p)?;
    let cos = n.dot(to_light);
    (cos > 0.0).then(|| (e * cos / std::f32::consts::PI, to_light, dist))
}

/// Irradiance at `p` on a surface facing one punctual light (normal
/// incidence), unshadowed, with the direction and distance to the light:
/// I / d² × the spec's range window and cone falloff for point and spot
/// lights, E for a directional light.
pub fn punctual_incident(light: &Light, p: Vec3) -> Option<(Vec3, Vec3, f32)> {
    match light.kind {
        LightKind::Directional => Some((light.intensity, -light.direction, f32::INFINITY)),
        LightKind::Point | LightKind::Spot { .. } => {
            let d = light.position - p;
            let dist2 = d.length_squared();
            if dist2 <= 0.0 {
                return None;
            }
            let dist = dist2.sqrt();
            let to_light = d / dist;
            let mut atten = 1.0 / dist2;
            if let Some(range) = light.range.filter(|r| *r > 0.0) {
                // KHR_lights_punctual's recommended range window.
                atten *= (1.0 - (dist / range).powi(4)).clamp(0.0, 1.0);
            }
            if let LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } = light.kind
            {
                // The spec's smooth cone falloff.
                let scale = 1.0 / (inner_cone_angle.cos() - outer_cone_angle.cos()).max(0.001);
                let offset = -outer_cone_angle.cos() * scale;
                let cd = light.direction.dot(-to_light);
                let a = (cd * scale + offset).clamp(0.0, 1.0);
                atten *= a * a;
            }
            (atten > 0.0).then(|| (light.intensity * atten, to_light, dist))
        }
    }
}

/// True when nothing lies between `origin` and a punctual light found by
/// [`punctual_irradiance`] in direction `dir` at distance `dist` (infinite
/// for a directional light); the segment stops just short of the light.
pub fn punctual_unoccluded(rays: &RayCaster, origin: Vec3, dir: Vec3, dist: f32) -> bool {
    let tmax = if dist.is_finite() {
        dist * (1.0 - 1e-4)
    } else {
        f32::INFINITY
    };
    rays.unoccluded(origin, dir, tmax)
}

/// Stream purpose id of the samples over lights' extents.
pub(crate) const PURPOSE_EXTENT: u64 = crate::util::sampling::purpose::LIGHT_EXTENT;

/// Shadow rays per texel and light with a size (a sphere or a sun disk),
/// stratified over the light's extent.
pub const EXTENT_SAMPLES: u32 = 16;

/// A direction from a point towards `light`'s extent for unit-square
/// point `u`, uniform in the solid angle the extent subtends: a cone about
/// the centre's direction `to` of half-angle α/2 (a sun disk of angular
/// diameter α) or asin(R / d) (a sphere of radius R at distance `dist`
/// d; Shirley et al. 1996, "Monte Carlo techniques for direct lighting
/// calculations"). Returns the direction and the distance along it to the
/// sphere's near surface (∞ for the sun). For small extents, uniform in
/// solid angle is uniform over the disk the light shows, so the visible
/// fraction of the samples is the visible fraction of the light.
pub fn extent_sample(light: &Light, to: Vec3, dist: f32, u: Vec2) -> (Vec3, f32) {
    let sphere = !matches!(light.kind, LightKind::Directional);
    let cos_max = if sphere {
        let s = (light.radius / dist).min(1.0);
        (1.0 - s * s).max(0.0).sqrt()
    } else {
        (0.5 * light.angle).cos()
    };
    let cos_t = 1.0 - u.x * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * std::f32::consts::PI * u.y;
    let dir = to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t), to);
    let len = if sphere {
        // The near root of |dist·to − t·dir| = R.
        let b = dist * cos_t;
        let c = dist * dist - light.radius * light.radius;
        (b - (b * b - c).max(0.0).sqrt()).max(0.0)
    } else {
        f32::INFINITY
    };
    (dir, len)
}

/// The visible fraction of `light` from the points `from` (point, normal,
/// weight; the centre's direction and distance from each): one shadow ray
/// from each for a delta light (weighted); for a light with a size,
/// [`EXTENT_SAMPLES`] rays over its extent, stratified (strata paired with
/// the points at random), each weighted by its cosine, so an unshadowed
/// point sees exactly 1. Returns (fraction, rays).
pub fn light_visibility(
    rays: &RayCaster,
    light: &Light,
    from: &[(Vec3, Vec3, f32, Vec3, f32)],
    rng: &mut Stream,
) -> (f32, u64) {
    let total: f32 = from.iter().map(|f| f.2).sum();
    if from.is_empty() || total <= 0.0 {
        return (0.0, 0);
    }
    if !light.has_extent() {
        // Weights summed in `total`'s order: a wholly lit texel sees 1.
        let mut visible = 0.0;
        for &(p, n, w, to, dist) in from {
            if punctual_unoccluded(rays, offset_ray_origin(p, n), to, dist) {
                visible += w;
            }
        }
        return ((visible / total).min(1.0), from.len() as u64);
    }
    let perm = rng.permutation(EXTENT_SAMPLES);
    let (mut seen, mut all, mut cast) = (0.0f32, 0.0f32, 0u64);
    for j in 0..EXTENT_SAMPLES {
        let (p, n, w, to, dist) = from[j as usize % from.len()];
        let u = stratified(perm[j as usize], EXTENT_SAMPLES, rng.next_vec2());
        let (dir, len) = extent_sample(light, to, dist, u);
        let c = n.dot(dir);
        if c <= 0.0 {
            continue;
        }
        cast += 1;
        all += w * c;
        if punctual_unoccluded(rays, offset_ray_origin(p, n), dir, len) {
            seen += w * c;
        }
    }
    (if all > 0.0 { seen / all } else { 0.0 }, cast)
}

/// Which materials' emission is sampled as direct light (per
/// [`EmitterSampling`]: `auto` samples a material that covers at most 2 %
/// of the surface); the rest enters the radiosity solve.
pub fn sampled_materials(scene: &Scene, geometry: &Geometry, mode: EmitterSampling) -> Vec<bool> {
    let mut area = vec![0.0f64; scene.materials.len()];
    let mut total = 0.0f64;
    for (t, &m) in geometry.material.iter().enumerate() {
        area[m as usize] += geometry.area[t] as f64;
        total += geometry.area[t] as f64;
    }
    scene
        .materials
        .iter()
        .enumerate()
        .map(|(m, mat)| {
            mat.is_emissive()
                && match mode {
                    EmitterSampling::Direct => true,
                    EmitterSampling::Radiosity => false,
                    EmitterSampling::Auto => area[m] <= 0.02 * total,
                }
        })
        .collect()
}

/// Sample counts of the two emitter estimators, for multiple importance
/// sampling with counts (Veach 1997, §9.2: wᵢ = (nᵢ pᵢ)² / Σⱼ (nⱼ pⱼ)²). The weights only
/// have to sum to one per direction for the sum to be unbiased, so the
/// hemisphere estimate may be made from any number of rays (a cheap
/// first-pass estimate, or the final gather's rays) with the same weights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mis {
    /// Light samples per texel.
    pub light: u32,
    /// Hemisphere rays per texel the weights assume.
    pub hemisphere: u32,
}

impl Mis {
    /// The hemisphere estimator's weight for a direction that light
    /// sampling picks with solid-angle pdf `p_l` and the cosine hemisphere
    /// with `p_b`; the light estimator's is one minus it. Power heuristic
    /// (β = 2, Veach 1997 §9.2.4): on the Cornell box's small lamp it gave
    /// a per-texel noise median of 0.52 % against the balance heuristic's
    /// 0.82 % (128 gather rays, 64 light samples; `tools/texel_noise`).
    pub fn hemisphere_weight(&self, p_l: f32, p_b: f32) -> f32 {
        let b = self.hemisphere as f32 * p_b;
        let l = self.light as f32 * p_l;
        let (b, l) = (b * b, l * l);
        b / (b + l)
    }
}

/// The radiance a cosine-weighted ray from normal `n` that escapes along
/// `dir` brings: a uniform sky's colour; a sky map's radiance times the
/// hemisphere estimator's MIS weight against its light samples
/// ([`sky_light`]; power heuristic with counts, as for the emitters).
pub fn escaped(lights: &Lights, mis: Mis, n: Vec3, dir: Vec3) -> Vec3 {
    let l = match &lights.sky {
        Sky::Uniform(c) => *c,
        Sky::Map(m) => {
            let p_b = n.dot(dir).max(0.0) / std::f32::consts::PI;
            m.radiance(dir) * lights.sky_mis(mis).hemisphere_weight(m.pdf(dir), p_b)
        }
    };
    l * lights.sky_weight()
}

/// The directional part b of a texel's light, one RGB vector per world axis
/// (x, y, z): with a = value − n_geo · b, irradiance / π for a normal n is
/// a + n · b — the linear (L1 spherical-harmonic) model
/// H(n) = (1/4π) ∫ L dω + (1/2π) n · ∫ L ω dω (Ramamoorthi & Hanrahan 2001).
pub type Directional = [Vec3; 3];
