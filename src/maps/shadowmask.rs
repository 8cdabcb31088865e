//! The shadowmask stage: the occlusion of each `shadowmask` light
//! ([`LightMode::Shadowmask`]) in one channel of RGBA pages, for engines
//! that draw such a light's direct light in real time and read its static
//! shadows from the bake (Unity's and Godot's shadowmask mode).
//!
//! 1. **Reach.** A light reaches a texel when any of the texel's pieces is
//!    within its range, inside its outer cone and in front of the piece
//!    (unshadowed irradiance > 0; no rays).
//! 2. **Channels.** Two lights overlap when one texel is reached by both.
//!    Channels are a greedy colouring of that overlap graph with four
//!    colours (Welsh & Powell 1967): lights in order of the texels they
//!    reach (most first; then scene order), each taking the lowest channel
//!    that no overlapping light holds. So no texel is reached by two lights
//!    of one channel, hence by at most four. A light left without a channel
//!    is baked as `indirect` instead, with a warning that names it.
//! 3. **Mask.** A channel's value at a texel is its light's visible fraction
//!    there: the texel's unshadowed irradiance from that light, summed over
//!    its pieces, times this value is the shadowed irradiance that the
//!    direct pass computes ([`TexelPieces::light`]: shadow rays from up to
//!    four pieces, or stratified over the light's extent where it has a
//!    size, so penumbrae are soft). 1 = unoccluded, 0 = in shadow, and 0
//!    where the channel's light does not reach the texel. The mask follows
//!    the texel's pieces whatever `supersample` says.
//! 4. **Pages.** Invalid texels are filled from their valid neighbours and
//!    the pages dilated, as for the lightmap ([`crate::maps::lightmap`]); seams
//!    are not stitched (a mask is 0 or 1 almost everywhere).

use crate::light::direct::TexelPieces;
use crate::maps::lightmap;
use crate::scene::{Light, LightMode};
use crate::surface::Surfaces;
use crate::util::sampling::Stream;
use glam::Vec3;
use rayon::prelude::*;

/// Stream purpose id of the shadowmask's samples over lights' extents.
const PURPOSE: u64 = crate::util::sampling::purpose::SHADOWMASK;

/// Channels of a shadowmask page (R, G, B, A).
pub const CHANNELS: usize = 4;

/// The channels' names, as the manifest, the report and the baked `.glb`
/// write them.
pub const CHANNEL_NAMES: [&str; CHANNELS] = ["r", "g", "b", "a"];

/// The mode `light` was baked in, given its `channel`: a shadowmask light
/// that got none was baked as `indirect`.
pub fn baked_mode(light: &Light, channel: Option<u8>) -> LightMode {
    match (light.mode, channel) {
        (LightMode::Shadowmask, None) => LightMode::Indirect,
        (m, _) => m,
    }
}

/// Shadowmask lights a scene may have (each texel tests each of them).
pub const MAX_LIGHTS: usize = 256;

/// The shadowmask stage's product.
#[derive(Clone, Debug, Default)]
pub struct Shadowmask {
    /// Per scene light (index in `Scene::lights`): its channel (0–3) where
    /// it is a shadowmask light that got one.
    pub channel: Vec<Option<u8>>,
    /// Shadowmask lights that got no channel (scene light indices): baked
    /// as `indirect`.
    pub fallback: Vec<usize>,
    /// Page width.
    pub width: u32,
    /// Page height.
    pub height: u32,
    /// Row-major RGBA visibility (0–1) per page.
    pub pages: Vec<Vec<[f32; CHANNELS]>>,
    /// Each texel's value (indexed by texel id), before filling.
    pub texel_values: Vec<[f32; CHANNELS]>,
    /// Shadow rays cast.
    pub rays: u64,
}

impl Shadowmask {
    /// The warnings of the stage: one per light that fell back.
    pub fn warnings(&self, lights: &[Light]) -> Vec<String> {
        self.fallback
            .iter()
            .map(|&l| {
                format!(
                    "shadowmask: light `{}` overlaps four lights that hold the four channels; it is baked as indirect (its direct light is the engine's, unmasked)",
                    lights[l].name
                )
            })
            .collect()
    }
}

/// Scene indices of the shadowmask lights.
pub fn lights(lights: &[Light]) -> Vec<usize> {
    (0..lights.len())
        .filter(|&l| lights[l].mode == LightMode::Shadowmask)
        .collect()
}

/// Step 1: which of `masked` (scene light indices) reaches each texel, as
/// an overlap bit matrix (row per light, `words` u64 per row) and the
/// count of texels each reaches.
fn reach(s: &Surfaces, masked: &[usize]) -> (Vec<u64>, Vec<u64>) {
    let n = masked.len();
    let words = n.div_ceil(64);
    let chunk = 1024;
    let texels = s.texels.len();
    let empty = || (vec![0u64; n * words], vec![0u64; n]);
    (0..texels.div_ceil(chunk))
        .into_par_iter()
        .fold(empty, |(mut overlap, mut count), c| {
            let mut hit = Vec::new();
            for t in c * chunk..((c + 1) * chunk).min(texels) {
                if s.burial.enclosed(t) {
                    continue;
                }
                let Some(pieces) = TexelPieces::new(s, t) else {
                    continue;
                };
                hit.clear();
                hit.extend((0..n).filter(|&k| pieces.reached_by(s, &s.scene.lights[masked[k]])));
                for &a in &hit {
                    count[a] += 1;
                    for &b in &hit {
                        overlap[a * words + b / 64] |= 1 << (b % 64);
                    }
                }
            }
            (overlap, count)
        })
        // Bitwise or and integer sums: the same whatever the split.
        .reduce(empty, |(mut o, mut k), (o2, k2)| {
            o.iter_mut().zip(o2).for_each(|(a, b)| *a |= b);
            k.iter_mut().zip(k2).for_each(|(a, b)| *a += b);
            (o, k)
        })
}

/// Step 2: channels by greedy colouring of the overlap graph (most-reaching
/// lights first); `None` where all four are taken by overlapping lights.
pub fn assign_channels(overlap: &[u64], count: &[u64]) -> Vec<Option<u8>> {
    let n = count.len();
    let words = n.div_ceil(64);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&k| (std::cmp::Reverse(count[k]), k));
    let mut channel: Vec<Option<u8>> = vec![None; n];
    for &a in &order {
        let mut taken = [false; CHANNELS];
        for b in 0..n {
            let overlaps = overlap[a * words + b / 64] >> (b % 64) & 1 == 1;
            if let (true, Some(c)) = (overlaps && b != a, channel[b]) {
                taken[c as usize] = true;
            }
        }
        channel[a] = (0..CHANNELS as u8).find(|&c| !taken[c as usize]);
    }
    channel
}

/// Step 3: each texel's mask (see the module doc), `by_channel` holding the
/// scene light indices of each channel.
fn masks(s: &Surfaces, by_channel: &[Vec<usize>; CHANNELS], seed: u64) -> (Vec<[f32; 4]>, u64) {
    let texels = s.texels.len();
    let chunk = 256;
    let parts: Vec<(Vec<[f32; 4]>, u64)> = (0..texels.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let mut out = Vec::with_capacity(chunk);
            let mut rays = 0;
            for t in c * chunk..((c + 1) * chunk).min(texels) {
                let mut mask = [0.0f32; CHANNELS];
                let pieces = (!s.burial.enclosed(t)).then(|| TexelPieces::new(s, t));
                if let Some(Some(mut pieces)) = pieces {
                    let mut rng = Stream::new(seed, PURPOSE, t as u64);
                    for (m, lights) in mask.iter_mut().zip(by_channel) {
                        // At most one of a channel's lights reaches a texel.
                        for &l in lights {
                            if let Some(seen) = pieces.light(s, &s.scene.lights[l], &mut rng) {
                                rays += seen.rays;
                                *m = seen.visible;
                                break;
                            }
                        }
                    }
                }
                out.push(mask);
            }
            (out, rays)
        })
        .collect();
    let mut values = Vec::with_capacity(texels);
    let mut rays = 0;
    for (v, r) in parts {
        values.extend(v);
        rays += r;
    }
    (values, rays)
}

/// The shadowmask of the scene's shadowmask lights (None when it has
/// none): channels, masks, then pages with invalid texels (`valid` false)
/// filled over `fill_rings` and `dilate` rings of dilation.
pub fn bake(
    s: &Surfaces,
    valid: &[bool],
    page_count: u32,
    (fill_rings, dilate): (u32, u32),
    seed: u64,
) -> Option<Shadowmask> {
    let masked = lights(&s.scene.lights);
    if masked.is_empty() {
        return None;
    }
    let (overlap, count) = reach(s, &masked);
    let assigned = assign_channels(&overlap, &count);
    let mut channel = vec![None; s.scene.lights.len()];
    let mut fallback = Vec::new();
    let mut by_channel: [Vec<usize>; CHANNELS] = Default::default();
    for (k, &l) in masked.iter().enumerate() {
        channel[l] = assigned[k];
        match assigned[k] {
            Some(c) => by_channel[c as usize].push(l),
            None => fallback.push(l),
        }
    }
    let (texel_values, rays) = masks(s, &by_channel, seed);
    let (width, height, pages) = pages(s, &texel_values, valid, page_count, (fill_rings, dilate));
    Some(Shadowmask {
        channel,
        fallback,
        width,
        height,
        pages,
        texel_values,
        rays,
    })
}

/// Step 4: RGBA pages, built as two RGB lightmaps (channels 0–2, and 3).
fn pages(
    s: &Surfaces,
    values: &[[f32; 4]],
    valid: &[bool],
    page_count: u32,
    (fill_rings, dilate): (u32, u32),
) -> (u32, u32, Vec<Vec<[f32; 4]>>) {
    let build = |pick: &dyn Fn(&[f32; 4]) -> Vec3| {
        let mut v: Vec<Vec3> = values.iter().map(pick).collect();
        lightmap::fill_invalid(s.texels, &mut v, valid, fill_rings);
        lightmap::build(s.texels, v, page_count, dilate)
    };
    let rgb = build(&|m| Vec3::new(m[0], m[1], m[2]));
    let a = build(&|m| Vec3::new(m[3], 0.0, 0.0));
    let pages = rgb
        .pages
        .iter()
        .zip(&a.pages)
        .map(|(rgb, a)| {
            rgb.iter()
                .zip(a)
                .map(|(c, a)| [c.x, c.y, c.z, a.x])
                .collect()
        })
        .collect();
    (rgb.width, rgb.height, pages)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric overlap matrix of `n` lights from pairs.
    fn graph(n: usize, pairs: &[(usize, usize)]) -> Vec<u64> {
        let words = n.div_ceil(64);
        let mut m = vec![0u64; n * words];
        for &(a, b) in pairs {
            m[a * words + b / 64] |= 1 << (b % 64);
            m[b * words + a / 64] |= 1 << (a % 64);
        }
        m
    }

    #[test]
    fn five_mutually_overlapping_lights_leave_the_least_reaching_out() {
        let pairs: Vec<_> = (0..5)
            .flat_map(|a| (a + 1..5).map(move |b| (a, b)))
            .collect();
        let c = assign_channels(&graph(5, &pairs), &[10, 50, 30, 40, 20]);
        assert_eq!(c[0], None, "{c:?}");
        let mut got: Vec<u8> = c.iter().flatten().copied().collect();
        got.sort();
        assert_eq!(got, [0, 1, 2, 3]);
    }

    #[test]
    fn lights_apart_share_a_channel() {
        // A chain 0–1–2–3–4–5: two channels suffice.
        let pairs = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5)];
        let c = assign_channels(&graph(6, &pairs), &[1; 6]);
        assert!(c.iter().all(|c| c.is_some_and(|c| c < 2)), "{c:?}");
        for (a, b) in pairs {
            assert_ne!(c[a], c[b]);
        }
    }

    #[test]
    fn sixty_five_lights_use_the_second_word() {
        // Light 64 overlaps light 0 only.
        let c = assign_channels(&graph(65, &[(0, 64)]), &[1; 65]);
        assert_ne!(c[0], c[64]);
        assert!(c.iter().all(Option::is_some));
    }
}
