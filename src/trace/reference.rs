//! Reference lightmap texels by path tracing ([`super::Tracer`]) from
//! points spread over each texel: the `pathtrace` transport method, and a
//! check of the bake that shares its texels and atlas (not independent of
//! them; [`super::measure`] is the check that shares none).

use super::Tracer;
use crate::layout::texels::Texels;
use crate::util::sampling::{stratified, Stream};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Stream purpose id of reference-texel paths.
const PURPOSE_TEXELS: u64 = crate::util::sampling::purpose::REFERENCE_TEXELS;

/// Reference lightmap texels: each texel's H/π by path tracing from
/// `samples` stratified points over it (`sample_texel(t, jitter, rng)`:
/// uniform over the texel's world area, all its pieces, so the estimate is
/// the exact texel mean), independent of patches and form factors. A texel whose first rays hit back faces more than
/// [`crate::surface::validity::BACKFACE_TOLERANCE`] of the time is marked invalid, as
/// in the final gather. Returns (values, validity, rays' paths started).
pub fn reference_texels(
    tracer: &Tracer,
    texels: &Texels,
    sample_texel: &(dyn Fn(u32, Vec2, &mut Stream) -> (Vec3, Vec3) + Sync),
    samples: u32,
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> (Vec<Vec3>, Vec<bool>) {
    let n = texels.len();
    let chunk = 64;
    let parts: Vec<Vec<(Vec3, bool)>> = (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let range = c * chunk..((c + 1) * chunk).min(n);
            let out: Vec<(Vec3, bool)> = range
                .map(|t| {
                    let mut rng = Stream::new(seed, PURPOSE_TEXELS, t as u64);
                    let mut sum = Vec3::ZERO;
                    let mut back = 0u32;
                    for k in 0..samples {
                        let jitter = stratified(k, samples, rng.next_vec2());
                        let (p, ng) = sample_texel(t as u32, jitter, &mut rng);
                        let (h, b) = tracer.incident(p, ng, &mut rng, 0);
                        sum += h;
                        back += b as u32;
                    }
                    let valid = back as f32
                        <= crate::surface::validity::BACKFACE_TOLERANCE * samples as f32;
                    (sum / samples.max(1) as f32, valid)
                })
                .collect();
            advance(out.len() as u64);
            out
        })
        .collect();
    parts.into_iter().flatten().unzip()
}
