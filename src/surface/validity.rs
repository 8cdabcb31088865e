//! Texel validity: a texel is invalid when more than the back-face
//! tolerance of its rays meet back faces, most of what it sees being the
//! inside of a solid (Unity's and Bakery's rule). The cheap estimate here
//! runs before the gather, so that buried texels can be filled in the
//! first-pass lightmap; the gather judges again from all of its rays.

use crate::surface::{texel_nets, texel_ray, Surfaces};
use crate::util::sampling::offset_ray_origin;
use rayon::prelude::*;

/// The default back-face tolerance (`backface_tolerance`): a texel is
/// invalid when more than this fraction of its rays hit back faces, most
/// of what it sees being the inside of a solid. (Unity's default is 0.1,
/// which also fails texels that lie partly under a wall; here the burial
/// planes ([`crate::surface::burial`]) keep their rays in open space, and one-sided
/// geometry seen from behind across a room is not burial.) The references
/// (path tracing, photon mapping) use it as well.
pub const BACKFACE_TOLERANCE: f32 = 0.5;

/// Texel validity's rule: more than `tolerance` of `rays` met back faces.
pub(crate) fn too_many_back_faces(back: u32, rays: u32, tolerance: f32) -> bool {
    back as f32 > tolerance * rays as f32
}

/// Rays per texel of the validity estimate made before the gather.
pub const VALIDITY_RAYS: u32 = 8;

/// Stream purpose id of the validity estimate's rays.
const VALIDITY_PURPOSE: u64 = crate::util::sampling::purpose::VALIDITY;

/// A cheap first estimate of texel validity (the gather's rule with
/// back-face `tolerance` on `rays` of its rays per texel), so texels buried
/// in geometry can be filled in the first-pass lightmap before the gather
/// reads it. Returns each texel's validity, whether every one of its rays
/// met a back face (it lies inside a solid), and the rays cast.
///
/// A texel stops casting once both answers are certain: valid when even
/// its remaining rays all meeting back faces would not make too many,
/// invalid (and not enclosed) once too many have and one has not. The
/// answers are those of casting every ray; an open texel casts half.
pub fn validity(s: &Surfaces, rays: u32, seed: u64, tolerance: f32) -> Validity {
    let n = s.texels.len();
    let chunk = 1024;
    let parts: Vec<Vec<(bool, bool, u32)>> = (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let range = c * chunk..((c + 1) * chunk).min(n);
            range
                .map(|t| {
                    let nets = texel_nets(seed, VALIDITY_PURPOSE, t);
                    let sampler = s.texel_sampler(t as u32);
                    let (mut back, mut cast) = (0u32, 0u32);
                    for k in 0..rays {
                        let (p, ng, dir) = texel_ray(&sampler, k, &nets);
                        cast += 1;
                        if s.meets_back_face(offset_ray_origin(p, ng), dir) {
                            back += 1;
                        }
                        if validity_settled(back, cast, rays, tolerance) {
                            break;
                        }
                    }
                    let (valid, enclosed) = validity_answers(back, rays, tolerance);
                    (valid, enclosed, cast)
                })
                .collect()
        })
        .collect();
    let mut v = Validity {
        valid: Vec::with_capacity(n),
        enclosed: Vec::with_capacity(n),
        rays: 0,
    };
    for (valid, enclosed, cast) in parts.into_iter().flatten() {
        v.valid.push(valid);
        v.enclosed.push(enclosed);
        v.rays += cast as u64;
    }
    v
}

/// Whether [`validity_answers`] for a texel are certain after `cast` of its
/// `rays` rays, `back` of them having met back faces: valid even if every
/// ray left met one, or invalid already with one ray that did not (so not
/// enclosed either).
fn validity_settled(back: u32, cast: u32, rays: u32, tolerance: f32) -> bool {
    let left = rays - cast;
    let surely_valid = !too_many_back_faces(back + left, rays, tolerance);
    let surely_invalid = too_many_back_faces(back, rays, tolerance) && back < cast;
    left > 0 && (surely_valid || surely_invalid)
}

/// A texel's validity and whether it is enclosed (all of its `rays` rays
/// met back faces), from the `back` of them that did.
fn validity_answers(back: u32, rays: u32, tolerance: f32) -> (bool, bool) {
    (
        !too_many_back_faces(back, rays, tolerance),
        back == rays && rays > 0,
    )
}

/// [`validity`]'s answers.
#[derive(Clone, Debug, Default)]
pub struct Validity {
    /// Per texel: not too many of its rays met back faces.
    pub valid: Vec<bool>,
    /// Per texel: every one of its rays met a back face.
    pub enclosed: Vec<bool>,
    /// Rays cast.
    pub rays: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stopping once [`validity_settled`] says so gives the answers of
    /// casting every ray: every sequence of back / front outcomes of 8 rays,
    /// at Unity's tolerance, radbake's and a high one.
    #[test]
    fn validity_stops_only_when_its_answers_are_settled() {
        let rays = 8u32;
        let mut stopped_early = 0;
        for tolerance in [0.0, 0.1, 0.5, 0.9] {
            for outcomes in 0u32..1 << rays {
                let back_of = |k: u32| outcomes >> k & 1;
                let all: u32 = (0..rays).map(back_of).sum();
                let (mut back, mut cast) = (0, 0);
                for k in 0..rays {
                    cast += 1;
                    back += back_of(k);
                    if validity_settled(back, cast, rays, tolerance) {
                        break;
                    }
                }
                stopped_early += (cast < rays) as u32;
                assert_eq!(
                    validity_answers(back, rays, tolerance),
                    validity_answers(all, rays, tolerance),
                    "outcomes {outcomes:08b}, tolerance {tolerance}, stopped after {cast}"
                );
            }
        }
        assert!(stopped_early > 500, "{stopped_early}");
    }
}
