//! Final gather: every texel's indirect light recomputed at the texel
//! (the "radiosity + ray tracing" two-pass method: a coarse radiosity
//! solution read back through per-texel rays).
//!
//! From points spread over the texel, N stratified cosine-weighted rays;
//! at each hit the outgoing radiance of the surface there is read from the
//! first pass: E′ + ρ̄ × H₁ of the hit texel, where ρ̄ is the texel's mean
//! albedo (over its footprint) and H₁ the first-pass
//! lightmap (the texel's own direct light, sharp, plus the interpolated
//! patch indirect light) and E′ the emission not already sampled as direct
//! light. The texel's final value is D (its direct light) + the gathered
//! mean, so the patch grid never shows and no interpolation crosses a wall.
//!
//! A ray that lands closer than about a texel reads the local lights'
//! direct light at its hit point instead of the hit texel's mean of it
//! ([`NearField`]).
//!
//! The same rays are the hemisphere samples of the texel's direct light:
//! the sky where they escape, sampled emitters with their MIS weight where
//! they meet one (see [`crate::light::direct::hemisphere_light`]).
//!
//! **Texel validity** (Unity's rule, with its tolerance raised): a texel
//! whose rays hit back faces in more than `backface_tolerance` of cases
//! (default [`BACKFACE_TOLERANCE`], a half) sees mostly the inside of a
//! solid; it is marked invalid and later filled from valid texels of its
//! chart. Partly buried texels are the burial planes' ([`crate::surface::burial`]).

use crate::light::direct::{hemisphere_light, local_light_at};
use crate::light::lights::{Directional, Lights, Mask, Mis};
use crate::radiosity::patch_lights::{power, PatchLights};
use crate::raycast::batch::BatchCaster;
use crate::raycast::Hit;
use crate::surface::validity::{too_many_back_faces, BACKFACE_TOLERANCE};
use crate::surface::{texel_nets, texel_ray, Landing, Surfaces};
use crate::util::sampling::{offset_ray_origin, Net, Stream};
use glam::Vec3;
use rayon::prelude::*;

/// Stream purpose id of final-gather rays.
const PURPOSE: u64 = crate::util::sampling::purpose::GATHER;

/// Stream purpose id of the gather's light samples ([`crate::radiosity::patch_lights`]).
const PURPOSE_NEE: u64 = crate::util::sampling::purpose::PATCH_LIGHTS;

/// Stream purpose id of the near field's direct-light samples
/// ([`NearField`]).
const PURPOSE_NEAR: u64 = crate::util::sampling::purpose::NEAR_FIELD;

/// The gather may stop early (under a tolerance below 0.9): after at least
/// 16 rays, more than 90 % met
/// back faces (a texel with half its hemisphere open does that with
/// probability 3·10⁻⁴ after 16 rays, less after more).
fn surely_buried(back: u32, cast: u32, tolerance: f32) -> bool {
    tolerance < 0.9 && cast >= 16 && back * 10 > cast * 9
}

/// A texel's net of light samples (patch and texel choice, point) and the
/// stream for a point's rare redraw.
fn nee_net(seed: u64, t: usize) -> (Net, Stream) {
    let mut rng = Stream::new(seed, PURPOSE_NEE, t as u64);
    (Net::shuffled(&mut rng), rng)
}

/// Rays a texel casts before their hits are read ([`Gatherer::texel`]): a
/// divisor of [`FIRST_CHECKPOINT`] and of `surely_buried`'s first count.
const GROUP: usize = 16;

/// The adaptive gather's first checkpoint: below it no variance estimate is
/// trusted.
const FIRST_CHECKPOINT: u32 = 32;

/// The adaptive gather's stopping rule at a checkpoint (a power of two ≥
/// [`FIRST_CHECKPOINT`], below the rays asked for): the estimated standard
/// error of the texel's total, √(s²/n), is at most `threshold` × the total
/// (`known` direct light + the gathered mean). Sunlit texels, whose total is
/// mostly the exactly sampled sun, stop early; shadowed ones, whose light
/// the gather carries, cast every ray. A texel whose rays have seen no
/// light yet never stops: its zero says nothing about what the rest would
/// find (the rays of a floor far from a lamp rarely meet it).
fn converged(sum: f32, sq: f32, n: u32, known: f32, threshold: f32) -> bool {
    if sum <= 0.0 {
        return false;
    }
    let nf = n as f32;
    let mean = sum / nf;
    let var = (sq / nf - mean * mean).max(0.0) * nf / (nf - 1.0);
    (var / nf).sqrt() <= threshold * (known + mean)
}

/// The gathered indirect light.
#[derive(Clone, Debug, Default)]
pub struct Gathered {
    /// Indirect irradiance / π per texel.
    pub indirect: Vec<Vec3>,
    /// Texel validity.
    pub valid: Vec<bool>,
    /// Variance of each texel's gathered mean (luminance): of everything
    /// its rays gathered, the indirect light and the direct light they
    /// estimate ([`Gathered::direct`]), which the denoiser filters
    /// together.
    pub variance: Vec<f32>,
    /// Directional part of all incident light seen by the gather rays
    /// (indirect, sky, emitters; see [`crate::light::lights::Directional`]); empty
    /// unless asked for.
    pub directional: Vec<Directional>,
    /// Ambient occlusion: the unoccluded fraction of the cosine-weighted
    /// hemisphere within the AO distance; empty unless asked for.
    pub ao: Vec<f32>,
    /// Direct light from the gather rays (sky and MIS-weighted emitters,
    /// see [`crate::light::direct::hemisphere_light`]); empty unless asked for.
    pub direct: Vec<Vec3>,
    /// Rays cast.
    pub rays: u64,
    /// Cosine rays each texel read (what a light layer's gather reads
    /// again, [`Gatherer::for_layer`]).
    pub cast: Vec<u32>,
}

/// What the gather computes besides the indirect light, and its validity
/// rule.
#[derive(Clone, Debug)]
pub struct Extras {
    /// Accumulate the directional (L1) part; needs the sky radiance.
    pub directional: bool,
    /// The sky (its radiance, for the directional part).
    pub sky: crate::light::sky::Sky,
    /// AO distance in metres (0: no AO).
    pub ao_distance: f32,
    /// The back-face tolerance of texel validity (`backface_tolerance`).
    pub backface_tolerance: f32,
    /// The adaptive gather's relative standard error (`gather_threshold`;
    /// 0: every texel casts every ray). See [`converged`].
    pub threshold: f32,
}

impl Default for Extras {
    fn default() -> Self {
        Extras {
            directional: false,
            sky: crate::light::sky::Sky::default(),
            ao_distance: 0.0,
            backface_tolerance: BACKFACE_TOLERANCE,
            threshold: 0.0,
        }
    }
}

/// One texel's gather.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TexelGather {
    mean: Vec3,
    valid: bool,
    variance: f32,
    directional: Directional,
    ao: f32,
    cast: u32,
    /// Light-sample rays cast ([`crate::radiosity::patch_lights`]).
    nee: u32,
    /// Rays cast in all (a few more than `cast + nee` where the texel was
    /// found invalid in mid-group).
    traced: u32,
    light: Vec3,
}

/// A texel's running sums over the rays it has read.
#[derive(Default)]
struct Sums {
    /// Indirect light.
    sum: Vec3,
    /// Rays that met back faces.
    back: u32,
    /// Luminance of each ray's whole contribution (indirect and hemisphere
    /// direct), and its square, for the stopping rule.
    all: f32,
    all_sq: f32,
    directional: Directional,
    /// Rays that met nothing within the AO distance.
    open: u32,
    /// Direct light from the rays.
    light: Vec3,
    /// Cosine rays read.
    cast: u32,
    /// Light samples cast.
    nee: u32,
}

impl Sums {
    /// The texel's gather from its sums, `traced` rays cast in all.
    fn finish(self, traced: u32, tolerance: f32) -> TexelGather {
        let n = self.cast as f32;
        let whole = self.all / n;
        TexelGather {
            mean: self.sum / n,
            valid: !too_many_back_faces(self.back, self.cast, tolerance)
                && !surely_buried(self.back, self.cast, tolerance),
            variance: ((self.all_sq / n - whole * whole).max(0.0)) / n,
            directional: self.directional.map(|b| b / n),
            ao: self.open as f32 / n,
            cast: self.cast,
            nee: self.nee,
            traced,
            light: self.light / n,
        }
    }
}

/// The gather's near field (the near/far split of Arikan et al. 2005,
/// "Fast and detail-preserving photon relaxation"). A ray that lands
/// closer than `radius` sees its hit texel over a large solid angle, where
/// the texel's light is not uniform, and the texel's mean direct light
/// misstates the part the ray sees. Near a local light it is far from
/// uniform: the strip of wall beside a lamp's 5 cm side face, lit by that
/// face, is brightest where the face sees it (the generated level's lamp
/// sides gathered 0.98 where the meter reads 1.73). Such a hit reflects the
/// local lights' direct light at the hit point instead
/// ([`crate::light::direct::local_light_at`]: point and spot lights, one emitter
/// sample and one cosine ray, MIS), plus the rest of the texel's light as
/// before: ρ̄ (H₁ − D_local + D_local(x)). The sun and the sky are left to
/// the texel's mean: their light varies within a texel only by shadows,
/// and re-reading them at every close hit cost Sponza 8 % of its bake for
/// no change in any instance's mean. Unbiased for D_local(x); only valid
/// hit texels are read so (an invalid texel's H₁ is its neighbours').
pub struct NearField<'a> {
    /// Per texel, the local lights' part of the direct light that H₁
    /// holds ([`crate::light::direct::Direct::local`]).
    pub direct: &'a [Vec3],
    /// Per texel, valid (the pre-gather estimate that filled H₁).
    pub valid: &'a [bool],
    /// The lights D_local was made of.
    pub lights: &'a Lights,
    /// Per instance: hits on it closer than this (metres) read the direct
    /// light at the point.
    pub radius: Vec<f32>,
    /// The largest `radius`: hits beyond it are not looked up.
    pub reach: f32,
}

impl<'a> NearField<'a> {
    /// The near field of `near` texels of each instance (`texel_size`,
    /// metres per texel side, per instance) over `direct`, `valid` and
    /// `lights`.
    pub fn new(
        near: f32,
        texel_size: &[f32],
        direct: &'a [Vec3],
        valid: &'a [bool],
        lights: &'a Lights,
    ) -> Self {
        let radius: Vec<f32> = texel_size.iter().map(|s| near * s).collect();
        let reach = radius.iter().copied().fold(0.0, f32::max);
        NearField {
            direct,
            valid,
            lights,
            radius,
            reach,
        }
    }
}

/// A texel's draws for its near field ([`Gatherer::near_light`]): its
/// stream (made at its first close hit) and the rays cast.
struct NearDraws {
    texel: usize,
    rng: Option<Stream>,
    traced: u32,
}

/// Everything a texel's gather reads: shared by the CPU gather and the
/// batched one ([`Gatherer::gather_batched`], the GPU's), which casts the same rays elsewhere.
pub struct Gatherer<'a> {
    s: &'a Surfaces<'a>,
    /// ρ̄ × H₁ per texel: the light a hit on it reflects.
    reflected: Vec<Vec3>,
    sampled: &'a [bool],
    rays: u32,
    seed: u64,
    extras: Extras,
    direct: Option<(&'a Lights, Mis)>,
    /// Per texel, the direct light the gather does not estimate (punctual
    /// lights, emitters' light samples): the adaptive gather's yardstick.
    known: Option<&'a [Vec3]>,
    /// Light samples towards bright patches, MIS-combined with the cosine
    /// rays ([`crate::radiosity::patch_lights`]); `None`: cosine rays alone.
    lights: Option<&'a PatchLights<'a>>,
    /// Direct light re-read at close hits; `None`: every hit reads its
    /// texel's.
    near: Option<NearField<'a>>,
    /// A light layer's gather ([`Gatherer::for_layer`]): its share of each
    /// light.
    layer: Option<&'a Mask>,
}

impl<'a> Gatherer<'a> {
    /// The gather of `rays` rays per texel over `first_pass` (H₁ per texel);
    /// the arguments as [`gather`]'s.
    pub fn new(
        s: &'a Surfaces<'a>,
        first_pass: &[Vec3],
        sampled: &'a [bool],
        rays: u32,
        seed: u64,
        extras: Extras,
        direct: Option<(&'a Lights, Mis)>,
    ) -> Self {
        // Light a hit reflects: the hit texel's mean albedo (over its
        // footprint, see `texels`) × its first-pass irradiance / π. One
        // lookup per hit, and no texture detail finer than a texel adds
        // noise to the gather.
        let reflected = s
            .texels
            .albedo
            .iter()
            .zip(first_pass)
            .map(|(&rho, &h)| rho * h)
            .collect();
        Gatherer {
            s,
            reflected,
            sampled,
            rays,
            seed,
            extras,
            direct,
            known: None,
            lights: None,
            near: None,
            layer: None,
        }
    }

    /// One light layer's gather ([`crate::scene::layers`]; run by
    /// [`gather_layers`]): hits read `mask`'s share of each material's
    /// emission (the first pass and the lights are the layer's already).
    pub fn for_layer(mut self, mask: &'a Mask) -> Self {
        self.layer = Some(mask);
        self
    }

    /// Per texel, the outgoing radiance a gather ray reads where it lands
    /// on the texel's front: ρ̄ × H₁ plus the emission the direct light
    /// does not sample (what [`crate::radiosity::patch_lights::PatchLights`] weighs patches by).
    pub fn texel_radiance(&self) -> Vec<Vec3> {
        let (s, g) = (self.s, self.s.geometry);
        (0..s.texels.len())
            .map(|t| {
                let m = g.material[s.texels.triangle[t] as usize] as usize;
                let e = if self.sampled[m] {
                    Vec3::ZERO
                } else {
                    s.texels.emission[t]
                };
                self.reflected[t] + e
            })
            .collect()
    }

    /// Hits closer than `near.radius` read the direct light where they
    /// land ([`NearField`]).
    pub fn with_near(mut self, near: NearField<'a>) -> Self {
        self.near = Some(near);
        self
    }

    /// What a hit on texel `h` at `hit` (a ray from `origin` along `dir`)
    /// reflects beyond [`Gatherer::read`]'s texel mean, in the near field:
    /// ρ̄ (D_local(x) − D_local) at the hit point x (its rays counted in
    /// `draws`); nothing beyond the radius.
    #[inline(always)]
    fn near_light(
        &self,
        h: u32,
        hit: &Hit,
        (origin, dir): (Vec3, Vec3),
        draws: &mut NearDraws,
    ) -> Vec3 {
        let Some(near) = &self.near else {
            return Vec3::ZERO;
        };
        if hit.t >= near.reach {
            return Vec3::ZERO;
        }
        let instance = self.s.texels.instance[h as usize] as usize;
        if hit.t >= near.radius[instance] || !near.valid[h as usize] {
            return Vec3::ZERO;
        }
        let t = draws.texel;
        let rng = (draws.rng).get_or_insert_with(|| Stream::new(self.seed, PURPOSE_NEAR, t as u64));
        let ng = self.s.geometry.ng_ws[hit.tri as usize];
        let n = if ng.dot(dir) < 0.0 { ng } else { -ng };
        let (d, cast) = local_light_at(self.s, near.lights, (origin + dir * hit.t, n), rng);
        draws.traced += cast as u32;
        let h = h as usize;
        self.s.texels.albedo[h] * (d - near.direct[h])
    }

    /// Adds light samples towards `lights`' patches to every texel's gather.
    pub fn with_lights(mut self, lights: &'a PatchLights<'a>) -> Self {
        self.lights = Some(lights);
        self
    }

    /// Rays each texel may cast: the cosine rays, then as many light
    /// samples where there are lights.
    fn rays_per_texel(&self) -> usize {
        self.rays as usize * if self.lights.is_some() { 2 } else { 1 }
    }

    /// What a gather ray reads where it lands on texel `h` at `hit`: ρ̄ ×
    /// H₁, plus the surface's emission (front only) unless the direct light
    /// samples it; and that sampled emission apart (the directional part
    /// sees it).
    ///
    /// Also the emission that a light layer's read adds its share of
    /// ([`LayerReads::read_ray`]): the front's emission where the direct
    /// light does not sample it (zero elsewhere), and the hit's material.
    #[inline(always)]
    fn read(&self, h: u32, hit: &Hit, dir: Vec3) -> (Vec3, Vec3, (Vec3, u32)) {
        let g = self.s.geometry;
        let tri = hit.tri as usize;
        let m = g.material[tri];
        let mut l = self.reflected[h as usize];
        let front = g.ng_ws[tri].dot(dir) < 0.0;
        let mut sampled = Vec3::ZERO;
        let mut unsampled = Vec3::ZERO;
        if front {
            // A surface that emits nothing is read without its texture
            // coordinates: one load fewer per hit.
            let material = &self.s.scene.materials[m as usize];
            let e = if material.is_emissive() {
                self.s.scene.emission_at(m, g.uv0_at(hit.tri, hit.u, hit.v))
            } else {
                material.emission
            };
            if !self.sampled[m as usize] {
                l += e;
                unsampled = e;
            } else if self.extras.directional {
                sampled = e;
            }
        }
        (l, sampled, (unsampled, m))
    }

    /// Texel `t`'s lights, if its patch has any: the lights, the patch, and
    /// the texel's net and stream for its light samples.
    fn texel_lights(&self, t: usize) -> Option<TexelLights<'_>> {
        let lights = self.lights?;
        let patch = self.s.patches.of_texel[t].0;
        lights.lit(patch).then(|| {
            let (net, rng) = nee_net(self.seed, t);
            TexelLights {
                lights,
                patch,
                net,
                rng,
            }
        })
    }

    /// The direct light per texel that the gather's rays do not estimate,
    /// against which the adaptive gather ([`Extras::threshold`]) judges a
    /// texel's noise.
    pub fn with_known(mut self, known: &'a [Vec3]) -> Self {
        self.known = Some(known);
        self
    }

    /// Every ray texel `t` may cast, in order (origin off the surface,
    /// direction): what [`Gatherer::texel`] casts, before it stops early
    /// on an invalid texel.
    fn rays_of(&self, t: usize, out: &mut [(Vec3, Vec3)]) {
        let nets = texel_nets(self.seed, PURPOSE, t);
        let mut tl = self.texel_lights(t);
        let sampler = self.s.texel_sampler(t as u32);
        let n = self.rays as usize;
        for k in 0..n.min(out.len()) {
            let (p, ng, dir) = texel_ray(&sampler, k as u32, &nets);
            let o = offset_ray_origin(p, ng);
            out[k] = (o, dir);
            if let Some(slot) = out.get_mut(n + k) {
                // A light sample's ray; the cosine ray's again where the
                // texel has none (its hit is not read).
                let ls = tl
                    .as_mut()
                    .and_then(|tl| tl.sample(self.s, o, ng, k as u32));
                *slot = (o, ls.map_or(dir, |ls| ls.dir));
            }
        }
    }

    /// Texel `t`'s gather; `cast(k, origin, dir)` is the closest hit of its
    /// ray `k` (cosine rays 0..N, light samples N..2N). Inlined into each
    /// caller (the CPU gather and the batched one), as it was before the
    /// batched path had its own module: out of line it cost the Cornell
    /// bake 3.8 % more instructions.
    #[inline(always)]
    fn texel(&self, t: usize, cast: impl FnMut(u32, Vec3, Vec3) -> Option<Hit>) -> TexelGather {
        self.texel_with(t, None, cast)
    }

    /// [`Gatherer::texel`] and, in the same pass over its rays, each light
    /// layer's gather of `layers` (see [`gather_layers`]) into `out`.
    #[inline(always)]
    fn texel_with(
        &self,
        t: usize,
        layers: Option<(&LayerReads, &mut Vec<TexelGather>)>,
        mut cast: impl FnMut(u32, Vec3, Vec3) -> Option<Hit>,
    ) -> TexelGather {
        let (s, extras, rays) = (self.s, &self.extras, self.rays);
        if s.burial.enclosed(t) {
            // Every ray of the validity estimate met a back face: the texel
            // is inside a solid; it receives nothing (all zeros, invalid)
            // and is filled.
            if let Some((l, out)) = layers {
                out.extend(l.gatherers.iter().map(|_| TexelGather::default()));
            }
            return TexelGather::default();
        }
        let nets = texel_nets(self.seed, PURPOSE, t);
        let mut tl = self.texel_lights(t);
        let sampler = s.texel_sampler(t as u32);
        let known = self.known.map_or(0.0, |k| k[t].element_sum() / 3.0);
        // The rule judges the irradiance only: the directional part and AO
        // need every ray.
        let adaptive = extras.threshold > 0.0 && !extras.directional && extras.ao_distance <= 0.0;
        let mut sums = Sums::default();
        let mut traced = 0u32;
        let mut cast = |k: u32, origin: Vec3, dir: Vec3| {
            traced += 1;
            cast(k, origin, dir)
        };
        // Once more rays have met back faces than an invalid texel needs,
        // the texel is invalid whatever the rest would find (its value is
        // replaced from its chart), so stop: texels inside walls are a
        // quarter of Sponza's. The adaptive gather stops at its checkpoints.
        let stop = |x: &Sums| {
            too_many_back_faces(x.back, rays, extras.backface_tolerance)
                || surely_buried(x.back, x.cast, extras.backface_tolerance)
                || (adaptive
                    && x.cast >= FIRST_CHECKPOINT
                    && x.cast.is_power_of_two()
                    && converged(x.all, x.all_sq, x.cast, known, extras.threshold))
        };
        // The rays go out GROUP at a time and their hits are landed together
        // ([`Surfaces::land_many`]), then read one by one as before. The
        // stopping rules are checked before each ray as before, and before
        // each group is cast: the group is a divisor of the checkpoints and
        // of `surely_buried`'s first count, so only a texel found invalid
        // in mid-group casts rays it does not read.
        let mut group = [(Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO); GROUP];
        let mut hits = [None; GROUP];
        let mut landings = [Landing::Escaped; GROUP];
        let mut near = NearDraws {
            texel: t,
            rng: None,
            traced: 0,
        };
        // Each layer's sums and near-field draws.
        let mut layer_sums: Vec<(Sums, NearDraws)> = match &layers {
            Some((l, _)) => (l.gatherers.iter())
                .map(|_| {
                    let draws = NearDraws {
                        texel: t,
                        rng: None,
                        traced: 0,
                    };
                    (Sums::default(), draws)
                })
                .collect(),
            None => Vec::new(),
        };
        'rays: for k0 in (0..rays).step_by(GROUP) {
            if stop(&sums) {
                break;
            }
            let m = (rays - k0).min(GROUP as u32) as usize;
            for (i, (ray, hit)) in group.iter_mut().zip(&mut hits).take(m).enumerate() {
                let k = k0 + i as u32;
                let (p, ng, dir) = texel_ray(&sampler, k, &nets);
                let origin = offset_ray_origin(p, ng);
                *ray = (p, ng, dir, origin);
                *hit = cast(k, origin, dir);
            }
            s.land_many(&hits[..m], |i| group[i].2, &mut landings[..m]);
            // What each hit reads, all loaded before any is used (the hit
            // texels' light is megabytes away; see `land_many`).
            let mut reads = [(Vec3::ZERO, Vec3::ZERO); GROUP];
            let mut emitted = [(Vec3::ZERO, 0u32); GROUP];
            for i in 0..m {
                if let (Landing::Texel(h), Some(hit)) = (landings[i], &hits[i]) {
                    let (_, _, dir, origin) = group[i];
                    let (l, sampled, e) = self.read(h, hit, dir);
                    reads[i] = (l + self.near_light(h, hit, (origin, dir), &mut near), sampled);
                    emitted[i] = e;
                }
            }
            for i in 0..m {
                if stop(&sums) {
                    break 'rays;
                }
                let ray = (k0 + i as u32, group[i]);
                let met = (landings[i], hits[i], reads[i]);
                let (w, ray_light) = self.read_ray(&mut sums, (&mut tl, &mut near), ray, met, &mut cast);
                if let Some((l, _)) = &layers {
                    let met = (landings[i], hits[i], emitted[i]);
                    l.read_ray(&mut layer_sums, group[i], met, (w, ray_light));
                }
            }
        }
        if let Some((_, out)) = layers {
            out.extend(layer_sums.into_iter().map(|(mut x, draws)| {
                // The whole's validity, from the same rays.
                x.back = sums.back;
                x.finish(draws.traced, extras.backface_tolerance)
            }));
        }
        sums.finish(traced + near.traced, extras.backface_tolerance)
    }

    /// Adds ray `k` from `p` (normal `ng`, offset origin `origin`) along
    /// `dir` to a texel's sums, with what it met (where it landed, its hit,
    /// and [`Gatherer::read`]'s values there); and the texel's light sample
    /// `k`, cast with `cast`.
    #[inline(always)]
    fn read_ray(
        &self,
        sums: &mut Sums,
        (tl, near): (&mut Option<TexelLights>, &mut NearDraws),
        (k, (p, ng, dir, origin)): (u32, (Vec3, Vec3, Vec3, Vec3)),
        (landing, hit, (l, sampled)): (Landing, Option<Hit>, (Vec3, Vec3)),
        cast: &mut impl FnMut(u32, Vec3, Vec3) -> Option<Hit>,
    ) -> (f32, Vec3) {
        let (s, extras) = (self.s, &self.extras);
        sums.cast += 1;
        let mut mis = 1.0;
        // Radiance for the directional part: everything seen.
        let mut seen = Vec3::ZERO;
        let mut indirect = Vec3::ZERO;
        let mut ray_light = Vec3::ZERO;
        if let Some((lights, mis)) = self.direct {
            ray_light = hemisphere_light(s, lights, mis, (p, ng, dir), hit);
            sums.light += ray_light;
        }
        if extras.ao_distance > 0.0 && hit.is_none_or(|h| h.t >= extras.ao_distance) {
            sums.open += 1;
        }
        match (landing, hit) {
            (Landing::Texel(h), Some(hit)) => {
                // The cosine ray's MIS weight against the light samples.
                let w = tl.as_ref().map_or(1.0, |tl| {
                    let pn = self.light_pdf(tl.lights, tl.patch, h, &hit, dir);
                    power(ng.dot(dir) * std::f32::consts::FRAC_1_PI, pn)
                });
                mis = w;
                indirect = l * w;
                seen = indirect + sampled;
            }
            (Landing::BackFace, _) => sums.back += 1,
            (Landing::Escaped, _) => seen = extras.sky.radiance(dir),
            _ => {}
        }
        if extras.directional {
            sums.directional = add_directional(sums.directional, seen, ng, dir);
        }
        if let Some(tl) = tl.as_mut() {
            if let Some(ls) = tl.sample(s, origin, ng, k) {
                sums.nee += 1;
                let hit = cast(self.rays + k, origin, ls.dir);
                let (l, pn) = self.light_ray((tl.lights, tl.patch), (origin, &ls), hit, near);
                if pn > 0.0 {
                    let pc = ng.dot(ls.dir) * std::f32::consts::FRAC_1_PI;
                    // w_n f / p_n with f = L cos θ / π = L p_c.
                    let contribution = l * (power(pn, pc) * pc / pn);
                    indirect += contribution;
                    if extras.directional {
                        sums.directional =
                            add_directional(sums.directional, contribution, ng, ls.dir);
                    }
                }
            }
        }
        sums.sum += indirect;
        let whole = (indirect + ray_light).element_sum() / 3.0;
        sums.all += whole;
        sums.all_sq += whole * whole;
        (mis, ray_light)
    }

    /// What light sample `ls`'s ray reads, and its density p_n: the
    /// radiance where it lands if its first hit is the point it chose
    /// (within 10⁻³ of the distance) and on the patch of that point; else
    /// nothing (p_n = 0). The density is evaluated at the hit as for a
    /// cosine ray ([`Gatherer::light_pdf`]), so both strategies weigh a
    /// direction alike.
    #[inline(always)]
    fn light_ray(
        &self,
        (lights, patch): (&PatchLights, u32),
        (origin, ls): (Vec3, &crate::radiosity::patch_lights::LightSample),
        hit: Option<Hit>,
        near: &mut NearDraws,
    ) -> (Vec3, f32) {
        let s = self.s;
        let Some(hit) = hit else {
            return (Vec3::ZERO, 0.0);
        };
        if (hit.t - ls.dist).abs() > 1e-3 * ls.dist {
            return (Vec3::ZERO, 0.0);
        }
        let Landing::Texel(h) = s.land(hit.tri, hit.u, hit.v, ls.dir) else {
            return (Vec3::ZERO, 0.0);
        };
        if s.patches.of_texel[h as usize].0 != ls.patch {
            return (Vec3::ZERO, 0.0);
        }
        let pn = self.light_pdf(lights, patch, h, &hit, ls.dir);
        // The near field as for a cosine ray: both strategies estimate one
        // integrand.
        let l = self.read(h, &hit, ls.dir).0 + self.near_light(h, &hit, (origin, ls.dir), near);
        (l, pn)
    }

    /// p_n of a ray from a texel of patch `patch` that landed on texel `h`
    /// at `hit`.
    #[inline(always)]
    fn light_pdf(&self, lights: &PatchLights, patch: u32, h: u32, hit: &Hit, dir: Vec3) -> f32 {
        let j = self.s.patches.of_texel[h as usize].0;
        let ny = self.s.geometry.ng_ws[hit.tri as usize];
        lights.pdf(self.s, patch, j, dir, hit.t, ny)
    }

    /// Every texel's gather, its rays cast on the CPU.
    pub fn gather_cpu(&self, advance: &(dyn Fn(u64) + Sync)) -> Gathered {
        self.assemble(self.gather_range(0..self.s.texels.len(), advance))
    }

    /// The gathers of the texels of `range`, in order (each depends on its
    /// texel's index alone: `radbake shard` computes ranges apart).
    pub fn gather_range(
        &self,
        range: std::ops::Range<usize>,
        advance: &(dyn Fn(u64) + Sync),
    ) -> Vec<TexelGather> {
        let s = self.s;
        let chunk = 256;
        let (lo, hi) = (range.start, range.end);
        let parts: Vec<Vec<TexelGather>> = (0..(hi - lo).div_ceil(chunk))
            .into_par_iter()
            .map(|c| {
                let range = lo + c * chunk..(lo + (c + 1) * chunk).min(hi);
                let out: Vec<TexelGather> = range
                    .map(|t| self.texel(t, |_, o, d| s.rays.closest_hit(o, d, f32::INFINITY)))
                    .collect();
                advance(out.len() as u64);
                out
            })
            .collect();
        parts.into_iter().flatten().collect()
    }

    /// The texels' gathers, in texel order, as [`Gathered`].
    /// The gather with its rays cast by `caster` (the GPU of `device =
    /// "gpu"`) in batches: every ray a texel may cast is cast (the CPU
    /// stops early on texels found invalid), then each texel's gather runs
    /// on the CPU over those hits, in the same order, so the result is
    /// [`Gatherer::gather_cpu`]'s.
    ///
    /// # Errors
    /// The caster failed (the caller falls back to [`Gatherer::gather_cpu`]).
    pub fn gather_batched(
        &self,
        caster: &dyn BatchCaster,
        advance: &(dyn Fn(u64) + Sync),
    ) -> crate::Result<Gathered> {
        let n = self.s.texels.len();
        let per = self.rays_per_texel().max(1);
        let mut texels = Vec::with_capacity(n);
        caster.cast_batches(
            n,
            per,
            &|t, out| self.rays_of(t, out),
            &mut |items, _, hits| {
                let start = items.start;
                let done: Vec<_> = items
                    .into_par_iter()
                    .with_min_len(64)
                    .map(|t| {
                        let k0 = (t - start) * per;
                        self.texel(t, |k, _, _| hits[k0 + k as usize])
                    })
                    .collect();
                advance(done.len() as u64);
                texels.extend(done);
            },
        )?;
        Ok(self.assemble(texels))
    }

    pub fn assemble(&self, texels: impl IntoIterator<Item = TexelGather>) -> Gathered {
        let n = self.s.texels.len();
        let mut gathered = Gathered {
            indirect: Vec::with_capacity(n),
            valid: Vec::with_capacity(n),
            variance: Vec::with_capacity(n),
            directional: Vec::new(),
            ao: Vec::new(),
            direct: Vec::new(),
            rays: 0,
            cast: Vec::with_capacity(n),
        };
        for x in texels {
            gathered.rays += x.traced as u64;
            gathered.cast.push(x.cast);
            gathered.indirect.push(x.mean);
            gathered.valid.push(x.valid);
            gathered.variance.push(x.variance);
            if self.extras.directional {
                gathered.directional.push(x.directional);
            }
            if self.extras.ao_distance > 0.0 {
                gathered.ao.push(x.ao);
            }
            if self.direct.is_some() {
                gathered.direct.push(x.light);
            }
        }
        gathered
    }
}

/// The light layers a whole gather reads in its pass ([`gather_layers`]):
/// their gatherers ([`Gatherer::for_layer`]) and their reflected light
/// ρ̄ × H₁, texel-major (`[h × K + k]`: one cache line serves every layer
/// at a hit).
struct LayerReads<'a> {
    gatherers: &'a [Gatherer<'a>],
    reflected: Vec<Vec3>,
}

impl<'a> LayerReads<'a> {
    fn new(gatherers: &'a [Gatherer<'a>], n: usize) -> Self {
        let mut reflected = Vec::with_capacity(n * gatherers.len());
        for h in 0..n {
            reflected.extend(gatherers.iter().map(|g| g.reflected[h]));
        }
        LayerReads {
            gatherers,
            reflected,
        }
    }

    /// Adds one ray of the whole gather to every layer's sums: what it
    /// read where it landed, each layer's share — its ρ̄ × H₁, its share of
    /// the unsampled emission `e` of material `m` and its near field (as
    /// [`Gatherer::read`] and [`Gatherer::near_light`] read for the layer)
    /// — times the whole's MIS weight `w`; and the whole's hemisphere
    /// direct light `ray_light` times the layer's share of what the ray
    /// met (the sky where it escaped, the hit's emission otherwise: what
    /// [`hemisphere_light`] scales by a layer's mask, so the product is
    /// its value for the layer).
    #[inline(always)]
    fn read_ray(
        &self,
        sums: &mut [(Sums, NearDraws)],
        (_, _, dir, origin): (Vec3, Vec3, Vec3, Vec3),
        (landing, hit, (e, m)): (Landing, Option<Hit>, (Vec3, u32)),
        (w, ray_light): (f32, Vec3),
    ) {
        let n = self.gatherers.len();
        for (k, (g, (x, draws))) in self.gatherers.iter().zip(sums).enumerate() {
            let Some(mask) = g.layer else { continue };
            x.cast += 1;
            let mut light = Vec3::ZERO;
            if g.direct.is_some() {
                let share = match &hit {
                    None => mask.sky,
                    Some(h) => mask.material[g.s.geometry.material[h.tri as usize] as usize],
                };
                light = ray_light * share;
                x.light += light;
            }
            let mut indirect = Vec3::ZERO;
            match (landing, hit) {
                (Landing::Texel(h), Some(hit)) => {
                    let l = self.reflected[h as usize * n + k] + e * mask.material[m as usize];
                    let l = l + g.near_light(h, &hit, (origin, dir), draws);
                    indirect = l * w;
                }
                (Landing::BackFace, _) => x.back += 1,
                _ => {}
            }
            x.sum += indirect;
            let whole = (indirect + light).element_sum() / 3.0;
            x.all += whole;
            x.all_sq += whole * whole;
        }
    }
}

/// The whole gather and its light layers' ([`Gatherer::for_layer`]) in
/// one pass: each texel's rays are cast once, for the whole gather (on
/// `gpu` where there is one), and every hit is read for the whole and for
/// each layer at once ([`LayerReads`]). So the layers share the whole
/// gather's rays and its adaptive stops, and sum to it. Returns the whole
/// gather and the layers', in order.
///
/// The layers have no light samples of their own (`gather_nee` is not
/// baked with layers): the whole's must have none either.
///
/// # Errors
/// The GPU caster failed.
pub fn gather_layers(
    whole: &Gatherer,
    layers: &[Gatherer],
    gpu: Option<&dyn BatchCaster>,
    advance: &(dyn Fn(u64) + Sync),
) -> crate::Result<(Gathered, Vec<Gathered>)> {
    debug_assert!(whole.lights.is_none() && layers.iter().all(|l| l.layer.is_some()));
    let s = whole.s;
    let n = s.texels.len();
    let per = whole.rays_per_texel().max(1);
    let reads = LayerReads::new(layers, n);
    // Per chunk of texels: the whole's gathers, and the layers' (texel-
    // major, `[i × K + k]`).
    type Part = (Vec<TexelGather>, Vec<TexelGather>);
    let chunk_of = |ts: &mut dyn Iterator<Item = usize>,
                    cast: &dyn Fn(usize, u32, Vec3, Vec3) -> Option<Hit>|
     -> Part {
        let (mut wholes, mut ls) = (Vec::new(), Vec::new());
        for t in ts {
            wholes.push(whole.texel_with(t, Some((&reads, &mut ls)), |k, o, d| cast(t, k, o, d)));
        }
        (wholes, ls)
    };
    let mut parts: Vec<Part> = Vec::new();
    match gpu {
        Some(caster) => caster.cast_batches(
            n,
            per,
            &|t, out| whole.rays_of(t, out),
            &mut |items, _, hits| {
                let start = items.start;
                let cast = |t: usize, k: u32, _, _| hits[(t - start) * per + k as usize];
                let done: Vec<Part> = (items.into_par_iter().with_min_len(64))
                    .fold_chunks(64, Vec::new, |mut v, t| {
                        v.push(t);
                        v
                    })
                    .map(|ts| chunk_of(&mut ts.into_iter(), &cast))
                    .collect();
                advance(done.iter().map(|p| p.0.len() as u64).sum());
                parts.extend(done);
            },
        )?,
        None => {
            let chunk = 256;
            let cast = |_, _, o, d| s.rays.closest_hit(o, d, f32::INFINITY);
            parts = (0..n.div_ceil(chunk))
                .into_par_iter()
                .map(|c| {
                    let part = chunk_of(&mut (c * chunk..((c + 1) * chunk).min(n)), &cast);
                    advance(part.0.len() as u64);
                    part
                })
                .collect();
        }
    }
    // Each layer's gathers, then (the layers' parts freed) the whole's.
    let k = layers.len();
    let layer_gathers = (layers.iter().enumerate())
        .map(|(i, l)| l.assemble(parts.iter().flat_map(|(_, ls)| ls.iter().skip(i).step_by(k).copied())))
        .collect();
    for part in &mut parts {
        part.1 = Vec::new();
    }
    Ok((whole.assemble(parts.into_iter().flat_map(|(w, _)| w)), layer_gathers))
}

/// A texel's lights ([`Gatherer::texel_lights`]).
struct TexelLights<'a> {
    lights: &'a PatchLights<'a>,
    patch: u32,
    net: Net,
    /// For a light sample's point's rare redraw.
    rng: Stream,
}

impl TexelLights<'_> {
    /// Light sample `k` from `origin` (normal `ng`), if it lies above the
    /// horizon.
    #[inline(always)]
    fn sample(
        &mut self,
        s: &Surfaces,
        origin: Vec3,
        ng: Vec3,
        k: u32,
    ) -> Option<crate::radiosity::patch_lights::LightSample> {
        self.lights
            .sample(s, self.patch, origin, self.net.point(k), &mut self.rng)
            .filter(|ls| ng.dot(ls.dir) > 0.0)
    }
}

/// Adds radiance `seen` from `dir` to the directional sums over normal
/// `ng`: b = ∫ L ω dω / 2π with pdf cos θ / π, so each ray adds L ω /
/// (2 cos θ): its normal part is exactly n / 2; the tangential part is
/// divided by a cos θ clamped at 0.25, bounding its variance (grazing
/// light's tangential pull is underestimated). A light sample's
/// contribution, w_n L p_c / p_n, enters the same way.
#[inline(always)]
fn add_directional(mut sum: Directional, seen: Vec3, ng: Vec3, dir: Vec3) -> Directional {
    let cos = ng.dot(dir);
    let v = ng * 0.5 + (dir - ng * cos) * (0.5 / cos.max(0.25));
    for (c, b) in sum.iter_mut().enumerate() {
        *b += seen * v[c];
    }
    sum
}

/// Gathers `rays` rays per texel. `first_pass` is H₁ per texel; `sampled`
/// flags the materials whose emission is already in the direct light.
/// With `direct`, the rays also estimate the hemisphere part of the direct
/// light (sky, and the sampled emitters with the given MIS weights), which
/// the direct pass then only estimates roughly for H₁: the direct pass's
/// own hemisphere rays would duplicate these.
#[allow(clippy::too_many_arguments)]
pub fn gather(
    s: &Surfaces,
    first_pass: &[Vec3],
    sampled: &[bool],
    rays: u32,
    seed: u64,
    extras: Extras,
    direct: Option<(&Lights, Mis)>,
    advance: &(dyn Fn(u64) + Sync),
) -> Gathered {
    Gatherer::new(s, first_pass, sampled, rays, seed, extras, direct).gather_cpu(advance)
}
