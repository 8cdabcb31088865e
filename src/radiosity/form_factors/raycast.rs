//! Form factors by Monte Carlo ray casting (in the spirit of Wallace, Elmquist
//! & Haines 1989, but shooting from the patch): N rays leave uniformly
//! distributed points of patch i in cosine-weighted directions, so each ray
//! carries 1/N of i's diffuse emission and Fᵢⱼ ≈ (rays whose closest hit is
//! the front of patch j) / N. Directions are stratified over a √N × √N grid.

use super::{FormFactorStats, FormFactors};
use crate::raycast::batch::BatchCaster;
use crate::raycast::Hit;
use crate::surface::{Landing, Surfaces, TexelSampler};
use crate::util::sampling::{cosine_hemisphere, offset_ray_origin, stratified, to_world, Stream};
use glam::Vec3;
use rayon::prelude::*;

/// Stream purpose id of form-factor rays.
const PURPOSE: u64 = crate::util::sampling::purpose::FORM_FACTORS;

/// Computes every row of F by casting `rays_per_patch` rays from each patch.
/// `advance` is called with the number of patches done.
pub fn compute(
    s: &Surfaces,
    rays_per_patch: u32,
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> FormFactors {
    FormFactors::from_row_fn(
        s.patches.len(),
        |i| row(s, i, rays_per_patch, seed),
        advance,
    )
}

/// [`compute`] with the rays cast by `caster` (the GPU of `device =
/// "gpu"`) in batches: the same rays ([`row_rays`]) and the same rows
/// ([`row_from_hits`]), so the matrix is the CPU's.
///
/// # Errors
/// The caster failed (the caller falls back to [`compute`]).
pub fn compute_batched(
    s: &Surfaces,
    caster: &dyn BatchCaster,
    rays_per_patch: u32,
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> crate::Result<FormFactors> {
    let n = s.patches.len();
    let rpp = rays_per_patch.max(1) as usize;
    let mut rows = Vec::with_capacity(n);
    let mut stats = FormFactorStats::default();
    caster.cast_batches(
        n,
        rpp,
        // A patch of fewer rays than a whole block's fills its slots with
        // its last ray again; only its own rays are read.
        &|i, out| {
            let own = row_rays(s, i, patch_rays(s, i, rays_per_patch), seed);
            let last = own.last().copied().unwrap_or((Vec3::ZERO, Vec3::Z));
            for (k, slot) in out.iter_mut().enumerate() {
                *slot = own.get(k).copied().unwrap_or(last);
            }
        },
        &mut |items, rays, hits| {
            let start = items.start;
            let results: Vec<_> = items
                .into_par_iter()
                .map(|i| {
                    let first = (i - start) * rpp;
                    let k = first..first + patch_rays(s, i, rays_per_patch) as usize;
                    let r = if s.patch_buried(i) {
                        (Vec::new(), FormFactorStats::default())
                    } else {
                        row_from_hits(s, &rays[k.clone()], &hits[k])
                    };
                    advance(1);
                    r
                })
                .collect();
            for (r, st) in results {
                stats.add(&st);
                rows.push(r);
            }
        },
    )?;
    Ok(FormFactors::from_rows(n, rows, stats))
}

/// The rays row i casts: `rays_per_patch` for a whole k × k block (or a
/// larger patch), in proportion to its texels for a smaller one (a block
/// cut by a chart's border, a piece of one that burial planes split;
/// [`Patches::block_share`]), at least a quarter of them: the same rays
/// per texel, so about the same noise per unit of surface, where every
/// patch used to cast a whole block's rays. Sponza's form-factor rays
/// 11.92 → 6.45 M (its 4,562 charts leave most patches partial).
pub fn patch_rays(s: &Surfaces, i: usize, rays_per_patch: u32) -> u32 {
    let most = rays_per_patch.max(1);
    let n = (most as f32 * s.patches.block_share(i)).ceil() as u32;
    n.clamp((most / 4).max(1), most)
}

/// Row i of F, sorted by column, from [`patch_rays`] rays.
pub fn row(
    s: &Surfaces,
    i: usize,
    rays_per_patch: u32,
    seed: u64,
) -> (Vec<(u32, f32)>, FormFactorStats) {
    if s.patch_buried(i) {
        return (Vec::new(), FormFactorStats::default());
    }
    let rays = row_rays(s, i, patch_rays(s, i, rays_per_patch), seed);
    let hits: Vec<Option<Hit>> = rays
        .iter()
        .map(|&(o, d)| s.rays.closest_hit(o, d, f32::INFINITY))
        .collect();
    row_from_hits(s, &rays, &hits)
}

/// The `n_rays` rays (origin, unit direction) of row i: points spread
/// over patch i by area (strata paired at random with the direction strata,
/// Fisher–Yates), cosine-distributed stratified directions. Shared by the
/// CPU and GPU paths, so both cast the same rays.
pub fn row_rays(s: &Surfaces, i: usize, n_rays: u32, seed: u64) -> Vec<(Vec3, Vec3)> {
    let mut rng = Stream::new(seed, PURPOSE, i as u64);
    let area_strata = rng.permutation(n_rays);
    // Each texel's sampler is made once, for all the rays from it.
    let texels = s.patches.texels_of(i);
    let mut samplers: Vec<Option<TexelSampler>> = vec![None; texels.len()];
    (0..n_rays)
        .map(|k| {
            let area_u = area_strata[k as usize] as f32 + rng.next_f32();
            let pick = s.pick_texel(i, area_u / n_rays as f32);
            let sampler = samplers[pick].get_or_insert_with(|| s.texel_sampler(texels[pick]));
            let (p, ng) = sampler.sample(rng.next_vec2());
            let dir = to_world(
                cosine_hemisphere(stratified(k, n_rays, rng.next_vec2())),
                ng,
            );
            (offset_ray_origin(p, ng), dir)
        })
        .collect()
}

/// Row i of F from its rays' closest hits: each ray landing on the front
/// of patch j adds 1/N to Fᵢⱼ.
pub fn row_from_hits(
    s: &Surfaces,
    rays: &[(Vec3, Vec3)],
    hits: &[Option<Hit>],
) -> (Vec<(u32, f32)>, FormFactorStats) {
    let n_rays = rays.len().max(1);
    let mut stats = FormFactorStats {
        rays: rays.len() as u64,
        ..Default::default()
    };
    let mut patches: Vec<u32> = Vec::with_capacity(rays.len());
    let mut landings = vec![Landing::Escaped; hits.len()];
    s.land_many(hits, |i| rays[i].1, &mut landings);
    for landing in landings {
        match landing {
            Landing::Texel(t) => patches.push(s.patches.of_texel[t as usize].0),
            Landing::BackFace => stats.back_faces += 1,
            Landing::Unmapped => stats.unmapped += 1,
            Landing::Escaped => stats.escaped += 1,
        }
    }
    patches.sort_unstable();
    let w = 1.0 / n_rays as f32;
    let mut out: Vec<(u32, f32)> = Vec::new();
    for j in patches {
        match out.last_mut() {
            Some((c, f)) if *c == j => *f += w,
            _ => out.push((j, w)),
        }
    }
    (out, stats)
}
