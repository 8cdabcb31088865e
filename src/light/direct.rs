//! Direct light at every texel: emissive surfaces, `KHR_lights_punctual`
//! lights and a uniform sky, each with shadow rays, giving D = direct
//! incident irradiance / π (the first bounce of the radiosity system, and the
//! sharp part of the lightmap).
//!
//! - Emissive surfaces are sampled both by light sampling (a point on an
//!   emitter triangle picked by power, then uniformly by area) and by
//!   cosine-weighted hemisphere sampling, combined with the power heuristic
//!   (Veach & Guibas 1995): small lights get soft, low-noise shadows, large
//!   ones (a furnace) no variance blow-up near corners.
//! - Point and spot lights: H = I cos θ / (π d²) × the spec's range window
//!   and cone falloff; directional: H = E cos θ / π.
//! - Sky: cosine-weighted rays that leave the scene see radiance `sky`.
//!
//! With the final gather on, the gather's rays are the hemisphere samples
//! of the lightmap's direct light (see [`crate::radiosity::gather`]); this pass then
//! casts a quarter as many for the first-pass value that the solve and the
//! gather's hits read, where its extra noise averages out.

use crate::light::lights::*;
use crate::light::sky::SkyMap;
use crate::raycast::{Hit, RayCaster};
use crate::scene::Light;
use crate::surface::Surfaces;
use crate::util::sampling::{
    cosine_hemisphere, hammersley, offset_ray_origin, shadow_ray, stratified, to_world, Stream,
};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Stream purpose id of direct-light samples.
const PURPOSE: u64 = crate::util::sampling::purpose::DIRECT;

/// Direct irradiance / π over a texel: punctual lights exactly at its
/// `centre` points (point and normal; one shadow ray each), emitters by one light
/// sample from each of `points` (positions spread over the texel, so the
/// estimate is the texel's average), sky and emitters by one
/// cosine-weighted ray from each of `hemisphere` points; the two emitter
/// estimators are weighted by `mis`.
/// Returns the light samples' part incl. the baked punctual lights, the
/// mixed lights' part, the hemisphere rays' part, the baked punctual
/// lights' directional part and the rays cast.
pub fn direct_at(
    s: &Surfaces,
    lights: &Lights,
    mis: Mis,
    punctual_points: &[(Vec3, Vec3)],
    points: &[(Vec3, Vec3)],
    hemisphere: &[(Vec3, Vec3)],
    rng: &mut Stream,
) -> TexelDirect {
    direct_routed(s, lights, mis, (punctual_points, points, hemisphere), rng, &mut [])
}

/// Sample points on a texel (point, normal).
type Points<'a> = &'a [(Vec3, Vec3)];

/// [`direct_at`], and in the same pass each light layer's share
/// ([`Routed`]): every contribution the whole texel receives is added,
/// times the layer's share of its light, to each layer that holds the
/// light. A layer's part is then bit for bit what [`direct_at`] over the
/// layer's masked lights gives (the same rays and draws, each value the
/// same product), without casting the rays again.
pub fn direct_routed(
    s: &Surfaces,
    lights: &Lights,
    mis: Mis,
    (punctual_points, points, hemisphere): (Points, Points, Points),
    rng: &mut Stream,
    layers: &mut [Routed],
) -> TexelDirect {
    let g = s.geometry;
    let mut h = Vec3::ZERO;
    let mut mixed = Vec3::ZERO;
    let mut rays = 0u64;

    // Punctual lights, averaged over the supersampling points; their
    // directional part (see [`Directional`]) is exact: a light of
    // irradiance/π h from ω adds h/cos θ · ω.
    let mut dir_part: Directional = [Vec3::ZERO; 3];
    let mut local = Vec3::ZERO;
    let w = 1.0 / punctual_points.len().max(1) as f32;
    for &(p, n) in punctual_points {
        for (i, light) in lights.punctual.iter().enumerate() {
            if let Some((value, dir, dist)) = punctual_irradiance(light, p, n) {
                let (visible, cast) =
                    light_visibility(s.rays, light, &[(p, n, 1.0, dir, dist)], rng);
                rays += cast;
                if visible <= 0.0 {
                    continue;
                }
                for r in layers.iter_mut() {
                    let share = r.lights.punctual_weight(i);
                    if share != 0.0 {
                        r.punctual(light, (value * (visible * share)) * w);
                    }
                }
                let value = value * (visible * lights.punctual_weight(i));
                if light.is_local() {
                    local += value * w;
                }
                if light.mode.is_mixed() {
                    mixed += value * w;
                } else {
                    h += value * w;
                    let cos = n.dot(dir).max(1e-3);
                    for (c, b) in dir_part.iter_mut().enumerate() {
                        *b += value * (w * dir[c] / cos);
                    }
                }
            }
        }
    }

    let has_emitters = !lights.emitters.is_empty();
    if !has_emitters && lights.sky.is_black() {
        return TexelDirect {
            light: h,
            mixed,
            hemisphere: Vec3::ZERO,
            local,
            directional: dir_part,
            rays,
        };
    }

    // Hemisphere (BRDF) samples: emitters with MIS weights, sky unweighted.
    let mut hemi = Vec3::ZERO;
    let mut hemi_local = Vec3::ZERO;
    let nh = hemisphere.len() as u32;
    // Positions paired with direction strata by a random permutation, as
    // in the final gather: any fixed pairing (this used to be reverse
    // order) integrates over only n of the n² stratum pairs and is biased
    // where visibility depends on both (a plate seeing the sky past a
    // floor's edge read 4.7 % low at 64 samples).
    let perm = rng.permutation(nh);
    for k in 0..nh {
        let (p, n) = hemisphere[perm[k as usize] as usize];
        let origin = offset_ray_origin(p, n);
        let dir = to_world(cosine_hemisphere(stratified(k, nh, rng.next_vec2())), n);
        rays += 1;
        let hit = s.rays.closest_hit(origin, dir, f32::INFINITY);
        let v = hemisphere_light(s, lights, mis, (p, n, dir), hit);
        hemi += v;
        if hit.is_some() {
            // An emitter's (a ray that met a surface brings no sky).
            hemi_local += v;
        }
        for r in layers.iter_mut() {
            // The layer's share of what the ray met: what
            // `hemisphere_light` scales by for the layer's lights.
            let share = match &hit {
                None => r.lights.sky_weight(),
                Some(h) => r.lights.emission_weight(s.geometry.material[h.tri as usize]),
            };
            let v = v * share;
            r.d.hemisphere += v;
            if hit.is_some() {
                r.hemi_local += v;
            }
        }
    }
    if nh > 0 {
        hemi /= nh as f32;
        local += hemi_local / nh as f32;
        for r in layers.iter_mut() {
            r.d.hemisphere /= nh as f32;
            r.d.local += r.hemi_local / nh as f32;
        }
    }

    // Light samples: a Hammersley set with a random rotation per point,
    // mapped onto the emitters (first coordinate through the power CDF,
    // whose remainder and the second coordinate place the point on the
    // triangle), so samples stay stratified over the whole emitting surface.
    if has_emitters {
        let samples = points.len() as u32;
        let shift = rng.next_vec2();
        for k in 0..samples {
            let Some(ls) = lights.sample(g, hammersley(k, samples, shift)) else {
                break;
            };
            let (light, cast) = emitter_sample(s, lights, mis, points[k as usize], &ls);
            h += light;
            local += light;
            rays += cast;
            let m = g.material[ls.tri as usize];
            for r in layers.iter_mut() {
                let share = r.lights.emission_weight(m);
                if share != 0.0 {
                    r.d.light += light * share;
                    r.d.local += light * share;
                }
            }
        }
    }
    // A sky map's light samples (a uniform sky has only the cosine rays,
    // its ideal sampling already).
    if let Some(map) = lights.sky.map().filter(|m| !m.is_black()) {
        let n = lights.sky_samples;
        let (sky, cast) = sky_light(s.rays, map, lights.sky_mis(mis), points, n, rng.next_vec2());
        h += sky * lights.sky_weight();
        rays += cast;
        for r in layers.iter_mut() {
            if r.lights.sky_weight() != 0.0 {
                r.d.light += sky * r.lights.sky_weight();
            }
        }
    }
    TexelDirect {
        light: h,
        mixed,
        hemisphere: hemi,
        local,
        directional: dir_part,
        rays,
    }
}

/// `n` light samples of a sky map, from `points` (point and normal)
/// evenly strided (sample k from point k·len/n, so a stratified set stays
/// spread over the texel), unit-square points a Hammersley set turned by
/// `shift` and mapped through the map's luminance distribution
/// ([`SkyMap::sample`]); each unoccluded one weighted by the light
/// estimator's MIS weight against the cosine rays (see [`escaped`]).
/// Returns irradiance / π (the mean over the samples) and the shadow rays
/// cast; nothing without points.
pub fn sky_light(
    rays: &RayCaster,
    map: &SkyMap,
    mis: Mis,
    points: &[(Vec3, Vec3)],
    n: u32,
    shift: Vec2,
) -> (Vec3, u64) {
    let n = if points.is_empty() { 0 } else { n };
    let mut h = Vec3::ZERO;
    let mut cast = 0;
    for k in 0..n {
        let (p, normal) = points[k as usize * points.len() / n as usize];
        let (dir, pdf, l) = map.sample(hammersley(k, n, shift));
        let cos = normal.dot(dir);
        if pdf <= 0.0 || cos <= 0.0 {
            continue;
        }
        cast += 1;
        if !rays.unoccluded(offset_ray_origin(p, normal), dir, f32::INFINITY) {
            continue;
        }
        let p_b = cos / std::f32::consts::PI;
        // f / p_l · w_l with f = L cos θ / π.
        h += l * (p_b / pdf) * (1.0 - mis.hemisphere_weight(pdf, p_b));
    }
    (if n > 0 { h / n as f32 } else { h }, cast)
}

/// What one cosine-weighted hemisphere ray from `p` (normal `n`) along
/// `dir` brings to direct irradiance / π, before dividing by the rays cast:
/// the sky if it escaped (`hit` is `None`; [`escaped`]), a sampled
/// emitter's radiance times its hemisphere MIS weight if it met one from
/// the front, else nothing. Which texel the hit lands on does not matter,
/// so the callers do not look it up.
pub fn hemisphere_light(
    s: &Surfaces,
    lights: &Lights,
    mis: Mis,
    (p, n, dir): (Vec3, Vec3, Vec3),
    hit: Option<Hit>,
) -> Vec3 {
    let g = s.geometry;
    let Some(hit) = hit else {
        return escaped(lights, mis, n, dir);
    };
    let Some(k) = lights.emitter_index(hit.tri) else {
        return Vec3::ZERO;
    };
    let tri = hit.tri as usize;
    let front = g.ng_ws[tri].dot(dir) < 0.0;
    if !front {
        return Vec3::ZERO;
    }
    let le = s
        .scene
        .emission_at(g.material[tri], g.uv0_at(hit.tri, hit.u, hit.v))
        * lights.emission_weight(g.material[tri]);
    let p_b = n.dot(dir) / std::f32::consts::PI;
    let p_l = lights.pdf_solid_angle(g, k, p, p + dir * hit.t, g.ng_ws[tri]);
    le * mis.hemisphere_weight(p_l, p_b)
}

/// What light sample `ls` on the emitters brings to irradiance / π at `p`
/// (normal `n`), before dividing by the samples: L cos θ / π / p_l × the
/// light estimator's MIS weight against the cosine rays, `mis.light`
/// samples in all (Veach 1997, §9.2); nothing where it is behind either
/// surface or shadowed. Returns it and the shadow rays cast (0 or 1).
pub(crate) fn emitter_sample(
    s: &Surfaces,
    lights: &Lights,
    mis: Mis,
    (p, n): (Vec3, Vec3),
    ls: &EmitterSample,
) -> (Vec3, u64) {
    let g = s.geometry;
    let (e, tri, q, nq) = (ls.k, ls.tri, ls.point, ls.normal);
    let d = q - p;
    let dist = d.length();
    let dir = d / dist;
    let cos_p = n.dot(dir);
    let cos_q = nq.dot(-dir);
    if cos_p <= 0.0 || cos_q <= 0.0 {
        return (Vec3::ZERO, 0);
    }
    let (so, sd, len) = shadow_ray(p, n, q, nq);
    if !s.rays.unoccluded(so, sd, len) {
        return (Vec3::ZERO, 1);
    }
    let le = s
        .scene
        .emission_at(g.material[tri as usize], g.uv0_at(tri, ls.u, ls.v))
        * lights.emission_weight(g.material[tri as usize]);
    let p_l = lights.pdf_solid_angle(g, e, p, q, nq);
    let p_b = cos_p / std::f32::consts::PI;
    // f / p_l · w_l / n_l with f = L cos_p / π.
    let light = le * (p_b / p_l) * (1.0 - mis.hemisphere_weight(p_l, p_b)) / mis.light as f32;
    (light, 1)
}

/// The local lights' direct irradiance / π at one point `p` of a surface
/// (normal `n`; [`Lights::has_local`]): one sample of what [`direct_at`]
/// averages over a texel into [`TexelDirect::local`]. Point and spot
/// lights (baked and mixed) with their shadow rays; the emitters by one
/// light sample and one cosine-weighted ray, combined by MIS with counts
/// one and one (Veach 1997, §9.2; the ray counts only where it meets an
/// emitter). The final gather's near field reads it where a ray lands
/// closer than a texel's mean can stand for ([`crate::radiosity::gather::NearField`]).
/// Returns it and the rays cast.
pub fn local_light_at(
    s: &Surfaces,
    lights: &Lights,
    (p, n): (Vec3, Vec3),
    rng: &mut Stream,
) -> (Vec3, u64) {
    let mut h = Vec3::ZERO;
    let mut rays = 0u64;
    for (i, light) in lights.punctual.iter().enumerate() {
        if !light.is_local() {
            continue;
        }
        if let Some((value, dir, dist)) = punctual_irradiance(light, p, n) {
            let (visible, cast) = light_visibility(s.rays, light, &[(p, n, 1.0, dir, dist)], rng);
            rays += cast;
            h += value * (visible * lights.punctual_weight(i));
        }
    }
    if lights.emitters.is_empty() {
        return (h, rays);
    }
    let mis = Mis {
        light: 1,
        hemisphere: 1,
    };
    if let Some(ls) = lights.sample(s.geometry, rng.next_vec2()) {
        let (light, cast) = emitter_sample(s, lights, mis, (p, n), &ls);
        h += light;
        rays += cast;
    }
    let dir = to_world(cosine_hemisphere(rng.next_vec2()), n);
    rays += 1;
    if let Some(hit) = s
        .rays
        .closest_hit(offset_ray_origin(p, n), dir, f32::INFINITY)
    {
        h += hemisphere_light(s, lights, mis, (p, n, dir), Some(hit));
    }
    (h, rays)
}

/// A light layer's share of a texel's direct light, accumulated in the
/// whole texel's pass ([`direct_routed`], [`pieces_routed`]): the layer's
/// masked lights ([`Lights::masked`]) and its parts so far (no directional
/// part, no rays: the whole's pass casts them).
pub struct Routed<'a> {
    /// The layer's lights.
    pub lights: &'a Lights,
    /// Its direct light so far.
    pub d: TexelDirect,
    /// Its hemisphere rays' emitter part, before dividing by the rays.
    hemi_local: Vec3,
}

impl<'a> Routed<'a> {
    /// Nothing yet, for the layer of `lights`.
    pub fn new(lights: &'a Lights) -> Self {
        Routed {
            lights,
            d: TexelDirect::default(),
            hemi_local: Vec3::ZERO,
        }
    }

    /// Adds punctual `light`'s `value` (the layer's share) as
    /// [`direct_at`] adds it: to the local part for a local light, to the
    /// mixed or the baked part by its mode.
    fn punctual(&mut self, light: &Light, value: Vec3) {
        if light.is_local() {
            self.d.local += value;
        }
        if light.mode.is_mixed() {
            self.d.mixed += value;
        } else {
            self.d.light += value;
        }
    }
}

/// One texel's direct light, its parts apart (irradiance / π each).
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TexelDirect {
    /// Baked punctual lights and the emitters' light samples.
    pub light: Vec3,
    /// Mixed lights ([`LightMode::is_mixed`]): their direct light, which
    /// the lightmap leaves to the engine but the bounces carry.
    pub mixed: Vec3,
    /// Sky and the emitters' hemisphere samples.
    pub hemisphere: Vec3,
    /// The part of `light + mixed + hemisphere` from local lights
    /// ([`Lights::has_local`]: emitters, point and spot lights), whose
    /// light varies as 1/r² near them: what the final gather's near field
    /// re-reads at the point ([`local_light_at`]).
    pub local: Vec3,
    /// The baked punctual lights' directional part.
    pub directional: Directional,
    /// Rays cast.
    pub rays: u64,
}

/// Direct light per texel, its two parts kept apart so the final gather can
/// replace the hemisphere part with its own (more) rays.
#[derive(Clone, Debug, Default)]
pub struct Direct {
    /// Punctual lights and the emitters' light samples (irradiance / π).
    pub light: Vec<Vec3>,
    /// Sky and the emitters' hemisphere samples (irradiance / π).
    pub hemisphere: Vec<Vec3>,
    /// Mixed lights' direct light ([`TexelDirect::mixed`]; irradiance / π),
    /// in none of the other parts.
    pub mixed: Vec<Vec3>,
    /// The local lights' part of the others ([`TexelDirect::local`]).
    pub local: Vec<Vec3>,
    /// Baked punctual lights' directional part.
    pub directional: Vec<Directional>,
    /// Rays cast.
    pub rays: u64,
}

impl Direct {
    /// All the direct light that arrives per texel (`light + hemisphere +
    /// mixed`): what the texel reflects, for the bounces.
    pub fn total(&self) -> Vec<Vec3> {
        self.light
            .iter()
            .zip(&self.hemisphere)
            .zip(&self.mixed)
            .map(|((a, b), c)| *a + *b + *c)
            .collect()
    }

    /// The direct light the lightmap holds per texel (`light +
    /// hemisphere`): the mixed lights' is the engine's to draw.
    pub fn baked(&self) -> Vec<Vec3> {
        self.light
            .iter()
            .zip(&self.hemisphere)
            .map(|(a, b)| *a + *b)
            .collect()
    }
}

/// Shadow rays per punctual light and texel, at most.
const PIECE_RAYS: usize = 4;

/// Punctual lights over texel `t` from its pieces (the triangles covering
/// it, see [`crate::layout::texels::Piece`]): the unshadowed irradiance is summed
/// exactly over all pieces, each at its own point and normal,
/// U = Σ aᵢ Eᵢ(cos θᵢ)⁺ / Σ aᵢ; shadow rays from the four pieces with the
/// largest aᵢ Eᵢ (all of them if fewer) give the lit fraction of U,
/// weighted by aᵢ Eᵢ. Exact for an unshadowed texel however it is folded;
/// one ray for a texel that one triangle covers. (The world
/// centroid of a curved texel lies off the surface, in the surface's own
/// shadow: Sponza's roof read 5 % dark that way; one piece's normal for the
/// whole texel favours the larger, steeper facets.)
/// A light with a size ([`Light::has_extent`]) casts [`EXTENT_SAMPLES`]
/// rays over its extent from those pieces instead ([`light_visibility`]),
/// drawn from `seed`'s stream for the texel.
/// Returns the baked lights' irradiance / π (in `light`), the mixed
/// lights' (in `mixed`), the baked lights' directional part and the rays.
pub fn pieces_direct(s: &Surfaces, lights: &Lights, t: usize, seed: u64) -> TexelDirect {
    pieces_routed(s, lights, t, seed, &mut [])
}

/// [`pieces_direct`], and each light layer's share in the same pass (as
/// [`direct_routed`]).
pub fn pieces_routed(
    s: &Surfaces,
    lights: &Lights,
    t: usize,
    seed: u64,
    layers: &mut [Routed],
) -> TexelDirect {
    let mut out = TexelDirect::default();
    let Some(mut pieces) = TexelPieces::new(s, t) else {
        return out;
    };
    let n_texel = s.texels.n_ws[t];
    // Drawn from only by lights with a size.
    let mut rng = Stream::new(seed, PURPOSE_EXTENT, t as u64);
    for (i, light) in lights.punctual.iter().enumerate() {
        let Some(seen) = pieces.light(s, light, &mut rng) else {
            continue;
        };
        out.rays += seen.rays;
        if seen.visible <= 0.0 {
            continue;
        }
        for r in layers.iter_mut() {
            let share = r.lights.punctual_weight(i);
            if share != 0.0 {
                r.punctual(light, seen.unshadowed * (seen.visible * share));
            }
        }
        let value = seen.unshadowed * (seen.visible * lights.punctual_weight(i));
        if light.is_local() {
            out.local += value;
        }
        if light.mode.is_mixed() {
            out.mixed += value;
            continue;
        }
        out.light += value;
        // Directional part as for a single point (see [`direct_at`]), from
        // the texel's mean normal and the first lit piece's direction.
        let cos = n_texel.dot(seen.dir).max(1e-3);
        for (c, b) in out.directional.iter_mut().enumerate() {
            *b += value * (seen.dir[c] / cos);
        }
    }
    out
}

/// A texel's pieces, ready to be lit by one punctual light after another
/// (see [`pieces_direct`]).
pub struct TexelPieces<'a> {
    pieces: &'a [crate::layout::texels::Piece],
    total: f32,
    side: crate::layout::burial::Side<'a>,
    /// (point, normal, weight aᵢ·lum(Eᵢ), direction, distance) per lit
    /// piece of the current light: what [`light_visibility`] reads.
    lit: Vec<(Vec3, Vec3, f32, Vec3, f32)>,
}

/// What one punctual light does at a texel ([`TexelPieces::light`]).
#[derive(Clone, Copy, Debug)]
pub struct PiecesLight {
    /// Unshadowed irradiance / π, the area-weighted mean over the pieces.
    pub unshadowed: Vec3,
    /// The lit fraction of `unshadowed` (0–1).
    pub visible: f32,
    /// Direction to the light from the first lit piece.
    pub dir: Vec3,
    /// Shadow rays cast.
    pub rays: u64,
}

impl<'a> TexelPieces<'a> {
    /// Texel `t`'s pieces; None when it has none (or no area).
    pub fn new(s: &Surfaces<'a>, t: usize) -> Option<TexelPieces<'a>> {
        let pieces = s.texels.pieces_of(t);
        let total: f32 = pieces.iter().map(|p| p.area).sum();
        if pieces.is_empty() || total <= 0.0 {
            return None;
        }
        Some(TexelPieces {
            pieces,
            total,
            // Pieces' points on the texel's side of its burial planes.
            side: s.side(t),
            lit: Vec::with_capacity(pieces.len()),
        })
    }

    /// True when `light` reaches any piece (in range, in its cone, in
    /// front of the piece), shadows aside: no rays.
    pub fn reached_by(&self, s: &Surfaces, light: &Light) -> bool {
        let g = s.geometry;
        self.pieces.iter().any(|piece| {
            let p = self.side.fold(g.point(piece.tri, piece.u, piece.v));
            punctual_irradiance(light, p, g.ng_ws[piece.tri as usize])
                .is_some_and(|(v, _, _)| v.element_sum() > 0.0)
        })
    }

    /// [`TexelPieces::light`]'s unshadowed irradiance / π alone (no
    /// shadow rays); None where it reaches no piece.
    pub fn unshadowed(&self, s: &Surfaces, light: &Light) -> Option<Vec3> {
        let g = s.geometry;
        let mut unshadowed = Vec3::ZERO;
        let mut any = false;
        for piece in self.pieces {
            let p = self.side.fold(g.point(piece.tri, piece.u, piece.v));
            let n = g.ng_ws[piece.tri as usize];
            if let Some((value, _, _)) = punctual_irradiance(light, p, n) {
                if piece.area * value.element_sum() > 0.0 {
                    unshadowed += value * (piece.area / self.total);
                    any = true;
                }
            }
        }
        any.then_some(unshadowed)
    }

    /// `light` at the texel: the unshadowed irradiance summed exactly
    /// over the pieces and its lit fraction from up to [`PIECE_RAYS`] of
    /// them (see [`pieces_direct`]); None where it reaches no piece.
    pub fn light(&mut self, s: &Surfaces, light: &Light, rng: &mut Stream) -> Option<PiecesLight> {
        let g = s.geometry;
        self.lit.clear();
        let mut unshadowed = Vec3::ZERO;
        for piece in self.pieces {
            let p = self.side.fold(g.point(piece.tri, piece.u, piece.v));
            let n = g.ng_ws[piece.tri as usize];
            if let Some((value, dir, dist)) = punctual_irradiance(light, p, n) {
                let w = piece.area * value.element_sum();
                if w > 0.0 {
                    unshadowed += value * (piece.area / self.total);
                    self.lit.push((p, n, w, dir, dist));
                }
            }
        }
        if self.lit.is_empty() {
            return None;
        }
        // Shadow rays from the (up to) four pieces that carry the most of U;
        // their weighted lit fraction stands for the texel's. Chosen by
        // weight, not drawn at random: drawing made the lit fraction of a
        // texel of many small triangles vary from seed to seed (Sponza's
        // seed-to-seed noise RMS 0.88 % → 1.89 % with four random draws).
        if self.lit.len() > PIECE_RAYS {
            self.lit
                .select_nth_unstable_by(PIECE_RAYS - 1, |a, b| b.2.total_cmp(&a.2));
            self.lit.truncate(PIECE_RAYS);
        }
        let (visible, rays) = light_visibility(s.rays, light, &self.lit, rng);
        Some(PiecesLight {
            unshadowed,
            visible,
            dir: self.lit[0].3,
            rays,
        })
    }
}

/// Direct light at every texel (see [`direct_at`]): area lights and sky
/// averaged over the texel, punctual lights over its pieces (see
/// [`pieces_direct`]); `samples`
/// light samples and `hemisphere` hemisphere rays per texel, emitters
/// weighted by `mis`.
///
/// `supersample` s > 1 evaluates punctual lights at s × s points over the
/// texel instead of its centroid (antialiased shadow edges).
#[allow(clippy::too_many_arguments)]
pub fn texels(
    s: &Surfaces,
    lights: &Lights,
    samples: u32,
    hemisphere: u32,
    mis: Mis,
    supersample: u32,
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Direct {
    let n = s.texels.len();
    let settings = TexelSettings {
        samples,
        hemisphere,
        mis,
        supersample,
        seed,
    };
    assemble(texel_range(s, lights, &settings, 0..n, advance))
}

/// The settings of [`texels`], for [`texel_range`].
#[derive(Clone, Copy, Debug)]
pub struct TexelSettings {
    /// Light samples per texel.
    pub samples: u32,
    /// Hemisphere rays per texel.
    pub hemisphere: u32,
    /// The emitters' MIS weights.
    pub mis: Mis,
    /// Punctual lights at s × s points (s > 1).
    pub supersample: u32,
    /// The bake's seed.
    pub seed: u64,
}

/// [`texels`] over the texels of `range` only, in order (each texel's
/// light depends on its index alone, so a range computed on its own is
/// that range of the whole: `radbake shard`).
pub fn texel_range(
    s: &Surfaces,
    lights: &Lights,
    set: &TexelSettings,
    range: std::ops::Range<usize>,
    advance: &(dyn Fn(u64) + Sync),
) -> Vec<TexelDirect> {
    let chunk = 256;
    let (lo, hi) = (range.start, range.end);
    if lights.is_empty() {
        // Nothing to sample (the furnace's emitting walls enter the
        // solve; no lights, no sky): every texel's direct light is zero,
        // as `direct_at` finds it, without its 80 sample points (0.3 s of
        // the furnace box's bake).
        advance((hi - lo) as u64);
        return vec![TexelDirect::default(); hi - lo];
    }
    let out: Vec<Vec<TexelDirect>> = (0..(hi - lo).div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let range = lo + c * chunk..(lo + (c + 1) * chunk).min(hi);
            let vals: Vec<TexelDirect> = range.map(|t| texel_direct(s, lights, set, t, &mut [])).collect();
            advance(vals.len() as u64);
            vals
        })
        .collect();
    out.into_iter().flatten().collect()
}

/// [`texel_range`] over every texel with each light layer's share
/// (`layers`: the layers' masked lights) in the same pass
/// ([`direct_routed`]): the whole's texels, and per layer its texels,
/// each what [`texel_range`] over the layer's lights gives.
pub fn texel_range_layers(
    s: &Surfaces,
    lights: &Lights,
    layers: &[Lights],
    set: &TexelSettings,
    advance: &(dyn Fn(u64) + Sync),
) -> (Vec<TexelDirect>, Vec<Vec<TexelDirect>>) {
    let n = s.texels.len();
    let k = layers.len();
    if lights.is_empty() {
        advance(n as u64);
        return (vec![TexelDirect::default(); n], vec![vec![TexelDirect::default(); n]; k]);
    }
    let chunk = 256;
    let parts: Vec<(Vec<TexelDirect>, Vec<TexelDirect>)> = (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let range = c * chunk..((c + 1) * chunk).min(n);
            let (mut wholes, mut ls) = (Vec::with_capacity(range.len()), Vec::new());
            for t in range {
                let mut routed: Vec<Routed> = layers.iter().map(Routed::new).collect();
                wholes.push(texel_direct(s, lights, set, t, &mut routed));
                ls.extend(routed.into_iter().map(|r| r.d));
            }
            advance(wholes.len() as u64);
            (wholes, ls)
        })
        .collect();
    let per_layer = (0..k)
        .map(|i| parts.iter().flat_map(|(_, ls)| ls.iter().skip(i).step_by(k).copied()).collect())
        .collect();
    (parts.into_iter().flat_map(|(w, _)| w).collect(), per_layer)
}

/// Texel `t`'s direct light ([`texel_range`]), and `layers`' shares of it.
#[inline(always)]
fn texel_direct(
    s: &Surfaces,
    lights: &Lights,
    set: &TexelSettings,
    t: usize,
    layers: &mut [Routed],
) -> TexelDirect {
    let (samples, hemisphere, mis, supersample, seed) = (
        set.samples,
        set.hemisphere,
        set.mis,
        set.supersample,
        set.seed,
    );
    if s.burial.enclosed(t) {
        // Inside a solid (see `burial`): nothing arrives.
        return TexelDirect::default();
    }
    let mut rng = Stream::new(seed, PURPOSE, t as u64);
    // The texel's sampling constants, read once for all its points.
    let sampler = s.texel_sampler(t as u32);
    // One point: the texel's pieces (see `pieces_direct`);
    // s × s points: spread over the texel's square.
    let mut piece_layers: Vec<Routed> = layers.iter().map(|r| Routed::new(r.lights)).collect();
    let (centre, pieces) = if supersample <= 1 {
        (Vec::new(), pieces_routed(s, lights, t, seed, &mut piece_layers))
    } else {
        let m = supersample * supersample;
        let points = (0..m)
            .map(|k| sampler.sample(stratified(k, m, Vec2::splat(0.5))))
            .collect();
        (points, TexelDirect::default())
    };
    let mut spread = |count: u32| -> Vec<(Vec3, Vec3)> {
        (0..count)
            .map(|k| sampler.sample(stratified(k, count, rng.next_vec2())))
            .collect()
    };
    let points = spread(samples);
    let hemi_points = if hemisphere == samples {
        points.clone()
    } else {
        spread(hemisphere)
    };
    let all = (&centre[..], &points[..], &hemi_points[..]);
    let mut d = direct_routed(s, lights, mis, all, &mut rng, layers);
    for (bc, pc) in d.directional.iter_mut().zip(pieces.directional) {
        *bc += pc;
    }
    d.light += pieces.light;
    d.mixed += pieces.mixed;
    d.local += pieces.local;
    d.rays += pieces.rays;
    for (r, p) in layers.iter_mut().zip(piece_layers) {
        r.d.light += p.d.light;
        r.d.mixed += p.d.mixed;
        r.d.local += p.d.local;
    }
    d
}

/// The texels' direct light, in texel order, as [`Direct`].
pub fn assemble(texels: Vec<TexelDirect>) -> Direct {
    let n = texels.len();
    let mut d = Direct {
        light: Vec::with_capacity(n),
        hemisphere: Vec::with_capacity(n),
        mixed: Vec::with_capacity(n),
        local: Vec::with_capacity(n),
        directional: Vec::with_capacity(n),
        rays: 0,
    };
    for t in texels {
        d.light.push(t.light);
        d.hemisphere.push(t.hemisphere);
        d.mixed.push(t.mixed);
        d.local.push(t.local);
        d.directional.push(t.directional);
        d.rays += t.rays;
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::LightKind;

    #[test]
    fn point_light_inverse_square_and_cosine() {
        let light = Light::delta(
            "p",
            LightKind::Point,
            Vec3::splat(10.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::NEG_Y,
        );
        let (h, dir, d) = punctual_irradiance(&light, Vec3::new(2.0, 0.0, 0.0), Vec3::Y).unwrap();
        // cos θ = 2/√8, d² = 8: H = 10 · cos θ / (π · 8).
        let want = 10.0 * (2.0 / 8f32.sqrt()) / (std::f32::consts::PI * 8.0);
        assert!((h.x - want).abs() < 1e-6);
        assert!((d - 8f32.sqrt()).abs() < 1e-6 && dir.y > 0.0);
        assert!(punctual_irradiance(&light, Vec3::ZERO, Vec3::NEG_Y).is_none());
    }

    #[test]
    fn spot_cone_falloff() {
        let light = Light::delta(
            "s",
            LightKind::Spot {
                inner_cone_angle: 0.2,
                outer_cone_angle: 0.4,
            },
            Vec3::ONE,
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::NEG_Y,
        );
        let inside = punctual_irradiance(&light, Vec3::ZERO, Vec3::Y)
            .unwrap()
            .0
            .x;
        assert!((inside - 1.0 / std::f32::consts::PI).abs() < 1e-6);
        // Outside the outer cone: nothing.
        let x = 0.5f32.tan() * 1.0;
        assert!(punctual_irradiance(&light, Vec3::new(x, 0.0, 0.0), Vec3::Y).is_none());
    }
}
