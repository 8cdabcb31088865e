//! A live light's sun table: each patch's direct light from a sun of unit
//! irradiance, for every direction of the live grid
//! ([`radbake_live::directions`]), for the run time to interpolate.
//!
//! Each texel's value for direction ωₖ is what the direct-light stage
//! gives it for a directional light from ωₖ ([`TexelPieces::light`]: the
//! unshadowed irradiance summed exactly over the texel's pieces, its lit
//! fraction from shadow rays), and the patch's the area-weighted mean of
//! its texels', as the bake's patch direct light is
//! ([`crate::pipeline::first_pass`]). At a grid direction the table is
//! therefore the bake's patch direct light for that sun, to the byte's
//! precision: stored as round(255 π D), D = irradiance / π per W/m².

use crate::light::direct::TexelPieces;
use crate::light::lights::PURPOSE_EXTENT;
use crate::scene::Light;
use crate::surface::Surfaces;
use crate::util::sampling::Stream;
use glam::Vec3;
use rayon::prelude::*;

/// The table of `light` (a directional light: its size and mode are
/// kept, its direction and intensity replaced) over `grid` × `grid`
/// directions: grid² × P bytes, direction-major. `advance` is called with
/// each patch's texel count.
pub fn sun_table(
    s: &Surfaces,
    light: &Light,
    grid: u32,
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Vec<u8> {
    let towards: Vec<Vec3> = (0..grid * grid)
        .map(|k| Vec3::from(radbake_live::directions::node_direction(grid, k % grid, k / grid)))
        .collect();
    quantised(&patch_direct(s, light, &towards, seed, advance), towards.len())
}

/// The table of `light` along a sun path: one direction per sample of
/// `path` (towards the sun, unit), direction-major as [`sun_table`].
pub fn sun_table_along(
    s: &Surfaces,
    light: &Light,
    path: &[Vec3],
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Vec<u8> {
    quantised(&patch_direct_along(s, light, path, seed, advance), path.len())
}

/// Along a path, a texel's shadow rays are cast at every `PATH_STRIDE`-th
/// sample (and the last); between two that it sees wholly lit, or wholly
/// shadowed, its lit fraction is taken as theirs (its unshadowed
/// irradiance still computed exactly at every sample), and where they
/// differ every sample between is traced. Shadows move little over a few
/// samples (256 a day: ≈ 0.7° apart), so most texels cast a quarter of
/// the rays.
pub const PATH_STRIDE: usize = 4;

/// [`patch_direct`] along a path (`towards` in order along it): the same
/// values, but that a texel's lit fraction between two samples
/// [`PATH_STRIDE`] apart that agree on wholly lit or wholly shadowed is
/// taken as theirs (see [`sun_table_along`]). A light with an extent
/// (a sun disk) is traced at every sample.
pub fn patch_direct_along(
    s: &Surfaces,
    light: &Light,
    towards: &[Vec3],
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Vec<Vec<f32>> {
    let stride = if light.has_extent() { 1 } else { PATH_STRIDE };
    per_patch(s, light, towards, (seed, stride), advance)
}

/// Per patch, per direction of `towards`: D, each texel's shadow rays cast
/// at every `stride`-th direction (and the last) and between two only
/// where they differ ([`add_texel`]); `stride` 1 traces every direction.
fn per_patch(
    s: &Surfaces,
    light: &Light,
    towards: &[Vec3],
    (seed, stride): (u64, usize),
    advance: &(dyn Fn(u64) + Sync),
) -> Vec<Vec<f32>> {
    let dirs = turned(light, towards);
    (0..s.patches.len())
        .into_par_iter()
        .map(|i| {
            let mut acc = vec![0.0f32; dirs.len()];
            let texels = s.patches.texels_of(i);
            for &t in texels {
                let t = t as usize;
                if s.burial.enclosed(t) {
                    continue; // inside a solid: nothing arrives
                }
                if let Some(mut pieces) = TexelPieces::new(s, t) {
                    add_texel(s, (t, &mut pieces), &dirs, (seed, stride), &mut acc);
                }
            }
            advance(texels.len() as u64);
            let a = s.patches.area[i];
            acc.iter().map(|v| v / a).collect()
        })
        .collect()
}

/// Texel `t`'s area × D for each of `dirs` added to `acc`: traced at every
/// `stride`-th direction and the last; between two traced ones that see it
/// wholly lit or wholly shadowed, its lit fraction is theirs (the
/// unshadowed part still exact), else every one between is traced.
fn add_texel(
    s: &Surfaces,
    (t, pieces): (usize, &mut TexelPieces),
    dirs: &[Light],
    (seed, stride): (u64, usize),
    acc: &mut [f32],
) {
    let n = dirs.len();
    let area = s.texels.area[t];
    let traced = |pieces: &mut TexelPieces, k: usize| -> Option<(f32, f32)> {
        // The direct stage's stream for the texel's first light.
        let mut rng = Stream::new(seed, PURPOSE_EXTENT, t as u64);
        (pieces.light(s, &dirs[k], &mut rng)).map(|seen| (seen.unshadowed.x, seen.visible))
    };
    let mut coarse: Vec<(usize, Option<(f32, f32)>)> = Vec::new();
    let mut k = 0;
    while k < n {
        coarse.push((k, traced(pieces, k)));
        k = if k + 1 == n { n } else { (k + stride).min(n - 1) };
    }
    for w in coarse.windows(2) {
        let ((a, va), (b, vb)) = (w[0], w[1]);
        let same = match (va, vb) {
            (Some((_, x)), Some((_, y))) if x == y && (x == 0.0 || x == 1.0) => Some(x),
            _ => None,
        };
        for (k, acc_k) in acc.iter_mut().enumerate().take(b).skip(a + 1) {
            let v = match same {
                Some(vis) => pieces.unshadowed(s, &dirs[k]).map(|u| (u.x, vis)),
                None => traced(pieces, k),
            };
            if let Some((u, vis)) = v {
                *acc_k += u * vis * area;
            }
        }
    }
    for (k, v) in coarse {
        if let Some((u, vis)) = v {
            acc[k] += u * vis * area;
        }
    }
}

/// `light` at unit irradiance turned to each direction of `towards`.
fn turned(light: &Light, towards: &[Vec3]) -> Vec<Light> {
    (towards.iter())
        .map(|&d| Light {
            direction: -d,
            intensity: Vec3::ONE,
            ..light.clone()
        })
        .collect()
}

/// Per patch rows of D into the table's bytes, direction-major.
fn quantised(per_patch: &[Vec<f32>], n: usize) -> Vec<u8> {
    let p = per_patch.len();
    let mut table = vec![0u8; n * p];
    for (i, row) in per_patch.iter().enumerate() {
        for (k, &v) in row.iter().enumerate() {
            let q = (v * 255.0 * std::f32::consts::PI).round().clamp(0.0, 255.0);
            table[k * p + i] = q as u8;
        }
    }
    table
}

/// Per patch, per direction of `towards` (unit, towards the light): the
/// patch's direct light D (irradiance / π) from `light` turned to that
/// direction at unit irradiance, unquantised (see the module).
pub fn patch_direct(
    s: &Surfaces,
    light: &Light,
    towards: &[Vec3],
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Vec<Vec<f32>> {
    per_patch(s, light, towards, (seed, 1), advance)
}
