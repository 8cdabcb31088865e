//! Seam stitching. A surface that is continuous in the world but cut in the
//! atlas (a UV seam inside one mesh, or two meshes that touch, like modular
//! floor tiles) is sampled from two places of the lightmap; bilinear
//! filtering then shows a line unless both sides agree.
//!
//! Seam edges are found in world space (triangle edges with the same
//! endpoints, whose lightmap coordinates differ, and whose faces are within
//! 30° of each other: creases such as a room's corners are real shading
//! discontinuities and are left alone). Along each seam, pairs of points
//! every half texel are made to agree in the least-squares sense: the
//! bilinear sample on each side, Σ wᵢ vᵢ, is moved towards the pair's mean by
//! relaxation sweeps over the texels (padding texels included) that the
//! samples touch.
//!
//! Only one continuous surface seen from one side is stitched. Two faces
//! that meet at an edge are joined only where they lie on opposite sides
//! of it (not folded back, not overlapping), and each point pair only
//! where both texels are valid (not inside or under geometry) and the two
//! points see each other just above the surface. Game levels put walls
//! back to back: the two rooms' floors then meet under the wall, and
//! joining them carried the lit room's light into the sealed one.

use crate::layout::geometry::Geometry;
use crate::maps::lightmap::Lightmaps;
use crate::raycast::RayCaster;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Faces meeting at a seam must be within this angle to be stitched.
const MAX_SEAM_ANGLE_DEG: f32 = 30.0;

/// One point of a seam, seen from both sides.
#[derive(Clone, Copy, Debug)]
pub struct SeamSample {
    /// Page and texel coordinate on side A.
    pub a: (u32, Vec2),
    /// Page and texel coordinate on side B.
    pub b: (u32, Vec2),
}

/// Finds the seam samples of `geometry`: pairs that `rays` finds in sight
/// of each other, on texels that `valid(page, texel coordinate)` accepts.
pub fn find(
    geometry: &Geometry,
    rays: &RayCaster,
    valid: &(dyn Fn(u32, Vec2) -> bool + Sync),
) -> Vec<SeamSample> {
    // Every triangle edge under its key (sorted quantised endpoints), in
    // key order and, within a key, triangle and corner order; an edge met
    // by exactly two triangles is a candidate. (A sort, not a hash map:
    // Sponza's 786 k edges took a quarter of a second to hash, alone.)
    type Edge = ([i64; 3], [i64; 3]);
    let mut edges: Vec<(Edge, u32, u8, u8)> = (0..geometry.len())
        .into_par_iter()
        .flat_map_iter(|t| {
            let p = geometry.p_ws[t];
            [(0u8, 1u8), (1, 2), (2, 0)].map(|(i, j)| {
                let (a, b) = (quantise(p[i as usize]), quantise(p[j as usize]));
                let key = if a <= b { (a, b) } else { (b, a) };
                (key, t as u32, i, j)
            })
        })
        .collect();
    edges.par_sort_unstable_by_key(|&(key, t, i, _)| (key, t, i));
    let pairs: Vec<[(u32, usize, usize); 2]> = edges
        .chunk_by(|x, y| x.0 == y.0)
        .filter_map(|run| <&[_; 2]>::try_from(run).ok())
        .map(|run| run.map(|(_, t, i, j)| (t, i as usize, j as usize)))
        .collect();
    pairs
        .par_iter()
        .with_min_len(256)
        .flat_map_iter(|&pair| seam_of(geometry, rays, valid, pair))
        .collect()
}

/// A point quantised to 10 µm: edges whose quantised endpoints agree are
/// one edge ([`find`]).
fn quantise(p: Vec3) -> [i64; 3] {
    (p * 1e5).round().as_i64vec3().to_array()
}

/// The samples along the edge that triangles `a` (corners ia, ja) and `b`
/// share, if it is a seam of one surface ([`find`]).
fn seam_of(
    geometry: &Geometry,
    rays: &RayCaster,
    valid: &(dyn Fn(u32, Vec2) -> bool + Sync),
    [(ta, ia, ja), (tb, ib, jb)]: [(u32, usize, usize); 2],
) -> Vec<SeamSample> {
    let cos_max = MAX_SEAM_ANGLE_DEG.to_radians().cos();
    let (ta_u, tb_u) = (ta as usize, tb as usize);
    if geometry.ng_ws[ta_u].dot(geometry.ng_ws[tb_u]) < cos_max {
        return Vec::new();
    }
    // Orient B's corners like A's (same world endpoints).
    let pa = [geometry.p_ws[ta_u][ia], geometry.p_ws[ta_u][ja]];
    let (ib, jb) = if quantise(geometry.p_ws[tb_u][ib]) == quantise(pa[0]) {
        (ib, jb)
    } else {
        (jb, ib)
    };
    if !opposite_sides(geometry, ta_u, tb_u, pa) {
        return Vec::new(); // folded back or overlapping: not one surface
    }
    let la = [geometry.uv_lm[ta_u][ia], geometry.uv_lm[ta_u][ja]];
    let lb = [geometry.uv_lm[tb_u][ib], geometry.uv_lm[tb_u][jb]];
    let same_page = geometry.page[ta_u] == geometry.page[tb_u];
    if same_page && la[0].distance(lb[0]) < 1e-3 && la[1].distance(lb[1]) < 1e-3 {
        return Vec::new(); // shared edge inside one chart: no seam
    }
    // Nudge sample points a little into each triangle, so each side
    // reads its own chart's texels.
    let centre_a = geometry.uv_lm[ta_u].iter().sum::<Vec2>() / 3.0;
    let centre_b = geometry.uv_lm[tb_u].iter().sum::<Vec2>() / 3.0;
    let len = la[0].distance(la[1]).max(lb[0].distance(lb[1]));
    let n = (2.0 * len).ceil().max(1.0) as u32;
    let mut samples = Vec::new();
    for k in 0..n {
        let s = (k as f32 + 0.5) / n as f32;
        let ua = la[0].lerp(la[1], s);
        let ub = lb[0].lerp(lb[1], s);
        let ua = ua + (centre_a - ua).normalize_or_zero() * 0.01;
        let ub = ub + (centre_b - ub).normalize_or_zero() * 0.01;
        let (page_a, page_b) = (geometry.page[ta_u], geometry.page[tb_u]);
        if !valid(page_a, ua) || !valid(page_b, ub) {
            continue; // inside or under geometry on one side
        }
        if !in_sight(geometry, rays, (ta_u, tb_u), pa[0].lerp(pa[1], s)) {
            continue; // a wall stands on the seam
        }
        samples.push(SeamSample {
            a: (page_a, ua),
            b: (page_b, ub),
        });
    }
    samples
}

/// True when triangles `a` and `b`, which share the edge `edge`, lie on
/// opposite sides of it (each one's third corner on its own side), as the
/// two halves of one surface do.
fn opposite_sides(geometry: &Geometry, a: usize, b: usize, edge: [Vec3; 2]) -> bool {
    let e = edge[1] - edge[0];
    let away = |t: usize| {
        let c = geometry.p_ws[t].iter().sum::<Vec3>() / 3.0 - edge[0];
        c - e * (c.dot(e) / e.length_squared().max(f32::MIN_POSITIVE))
    };
    away(a).dot(away(b)) < 0.0
}

/// True when points just inside triangles `a` and `b` next to the seam
/// point `p`, lifted just above their faces, see each other: nothing
/// stands on the seam there. The points are a thousandth of the faces'
/// size from the seam and lifted as far, which keeps the segment between
/// them above a 30° crease.
fn in_sight(geometry: &Geometry, rays: &RayCaster, (a, b): (usize, usize), p: Vec3) -> bool {
    let lifted = |t: usize| {
        let c = geometry.p_ws[t].iter().sum::<Vec3>() / 3.0;
        let size = geometry.area[t].sqrt();
        let d = (1e-3 * size).max(1e-4);
        p + (c - p).normalize_or_zero() * d + geometry.ng_ws[t] * d
    };
    let (pa, pb) = (lifted(a), lifted(b));
    let along = pb - pa;
    let dist = along.length();
    dist <= 0.0 || rays.unoccluded(pa, along / dist, dist)
}

/// The four texels and bilinear weights of texel coordinate `uv`.
fn taps(uv: Vec2, w: u32, h: u32) -> [(usize, f32); 4] {
    let f = uv - 0.5;
    let x0 = f.x.floor();
    let y0 = f.y.floor();
    let (tx, ty) = (f.x - x0, f.y - y0);
    let clamp = |x: f32, n: u32| (x.max(0.0) as u32).min(n - 1) as usize;
    let (xa, xb) = (clamp(x0, w), clamp(x0 + 1.0, w));
    let (ya, yb) = (clamp(y0, h), clamp(y0 + 1.0, h));
    let wi = w as usize;
    [
        (ya * wi + xa, (1.0 - tx) * (1.0 - ty)),
        (ya * wi + xb, tx * (1.0 - ty)),
        (yb * wi + xa, (1.0 - tx) * ty),
        (yb * wi + xb, tx * ty),
    ]
}

fn sample(lm: &Lightmaps, (page, uv): (u32, Vec2)) -> Vec3 {
    taps(uv, lm.width, lm.height)
        .iter()
        .map(|&(i, w)| lm.pages[page as usize][i] * w)
        .sum()
}

/// Mean absolute difference (summed over RGB) of the bilinear samples on the
/// two sides of every seam sample.
pub fn mismatch(lm: &Lightmaps, samples: &[SeamSample]) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    samples
        .iter()
        .map(|s| (sample(lm, s.a) - sample(lm, s.b)).abs().element_sum() as f64)
        .sum::<f64>()
        / samples.len() as f64
}

/// [`stitch`] of `lm` with its light layers (`layers`, which sum to it):
/// each layer moves by its own share of each step, and a texel channel
/// that the whole map clamps at 0 is 0 in every layer, so the stitched
/// layers still sum to the stitched map.
pub fn stitch_layers(lm: &mut Lightmaps, layers: &mut [Lightmaps], samples: &[SeamSample], sweeps: u32) {
    let (w, h) = (lm.width, lm.height);
    for _ in 0..sweeps {
        for s in samples {
            let d = sample(lm, s.a) - sample(lm, s.b);
            let ta = taps(s.a.1, w, h);
            let tb = taps(s.b.1, w, h);
            let norm: f32 = ta.iter().chain(tb.iter()).map(|t| t.1 * t.1).sum();
            if norm <= 0.0 {
                continue;
            }
            let steps: Vec<Vec3> = (layers.iter())
                .map(|l| (sample(l, s.a) - sample(l, s.b)) / norm)
                .collect();
            let step = d / norm;
            for (side, taps, sign) in [(s.a.0, &ta, -1.0f32), (s.b.0, &tb, 1.0)] {
                for &(i, wt) in taps.iter() {
                    let v = &mut lm.pages[side as usize][i];
                    let moved = *v + step * (sign * wt);
                    let clamped = moved.cmplt(Vec3::ZERO);
                    *v = moved.max(Vec3::ZERO);
                    for (l, k) in layers.iter_mut().zip(&steps) {
                        let x = &mut l.pages[side as usize][i];
                        *x = Vec3::select(clamped, Vec3::ZERO, *x + *k * (sign * wt));
                    }
                }
            }
        }
    }
}

/// Makes both sides of every seam agree (`sweeps` relaxation sweeps, in a
/// fixed order, so the result is deterministic).
pub fn stitch(lm: &mut Lightmaps, samples: &[SeamSample], sweeps: u32) {
    let (w, h) = (lm.width, lm.height);
    for _ in 0..sweeps {
        for s in samples {
            let d = sample(lm, s.a) - sample(lm, s.b);
            let ta = taps(s.a.1, w, h);
            let tb = taps(s.b.1, w, h);
            let norm: f32 = ta.iter().chain(tb.iter()).map(|t| t.1 * t.1).sum();
            if norm <= 0.0 {
                continue;
            }
            // The smallest change (in the least-squares sense) that closes d.
            let step = d / norm;
            for &(i, wt) in &ta {
                let v = &mut lm.pages[s.a.0 as usize][i];
                *v = (*v - step * wt).max(Vec3::ZERO);
            }
            for &(i, wt) in &tb {
                let v = &mut lm.pages[s.b.0 as usize][i];
                *v = (*v + step * wt).max(Vec3::ZERO);
            }
        }
    }
}
