//! Patch lights: next-event estimation towards bright surfaces
//! for the final gather, from the solved radiosity field (the "combined
//! methods" of two-pass rendering: the first pass says where the light
//! comes from, the second samples it there).
//!
//! Every patch j of the solution is an area light of outgoing radiance
//! L̄ⱼ (its texels' ρ̄ × H₁ plus the emission the direct pass does not
//! sample, area-weighted). A texel of patch i picks a light from **row i of
//! the form-factor matrix**, by the contribution Fᵢⱼ · lum(L̄ⱼ) each patch
//! makes to patch i's irradiance / π: the rows were cast with visibility,
//! so in a shadowed arcade the sunlit patches that i actually sees are the
//! ones chosen, not the bright ones behind a wall (a light tree, Conty &
//! Kulla 2017, knows no visibility). Then a texel of j by area and a point
//! uniform over its surface ([`Surfaces::sample_texel_area`]), so the point
//! has density 1 / Aⱼ on the patch, and a ray towards it.
//!
//! **MIS.** The light sample and the gather's cosine ray are combined by
//! the power heuristic (Veach & Guibas 1995, eq. 9). In solid angle, a
//! direction ω whose first hit y lands on patch j has
//! p_n(ω) = P(j | i) · d² / (Aⱼ |cos θ_y|) and p_c(ω) = cos θ / π; a light
//! sample counts only where its ray's first hit is the point it chose, so
//! its density is the same function, and the two weights sum to one for
//! every direction: the combination is unbiased whatever the rows miss
//! (directions towards no chosen patch are the cosine rays' alone, at
//! weight one).
//!
//! **Near field.** A patch within two bounding radii of patch i (from any
//! point of i it spans more than 60°) stays in the cosine rays: there the
//! light sample's geometry term d⁻² varies wildly over the patch, while
//! cosine sampling is already near the ideal density. Patch i itself is
//! always left out (it cannot see itself), and so is every patch with a
//! texel that burial planes cross (its sample points are folded, so their
//! density is not 1 / Aⱼ).

use crate::radiosity::form_factors::Csr;
use crate::surface::Surfaces;
use crate::util::sampling::Stream;
use glam::{Vec2, Vec3};

/// The lights of every patch: row i of F with a cumulative distribution
/// over its entries.
pub struct PatchLights<'a> {
    f: &'a Csr,
    /// Per entry of `f` (same layout): the cumulative probability within
    /// its row, 1 at the row's last chosen entry; an entry left out has its
    /// predecessor's value (probability 0).
    cdf: Vec<f32>,
    /// Whether row i has any light.
    lit: Vec<bool>,
}

/// A light sample: a point on a patch and its density in solid angle.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the ray origin.
    pub dir: Vec3,
    /// Distance to the point; the ray counts only if its hit is there.
    pub dist: f32,
    /// The patch of the point.
    pub patch: u32,
    /// p_n(ω) = P(j | i) · d² / (Aⱼ |cos θ_y|).
    pub pdf: f32,
}

impl<'a> PatchLights<'a> {
    /// Lights for every patch of `s` over the form factors `f`, with
    /// `radiance` the outgoing radiance a gather ray reads per texel.
    pub fn build(s: &Surfaces, f: &'a Csr, radiance: &[Vec3]) -> PatchLights<'a> {
        let (centre, radius) = spheres(s);
        let usable = usable(s);
        let lum: Vec<f32> = patch_radiance(s, radiance)
            .iter()
            .map(|l| l.element_sum() / 3.0)
            .collect();
        let mut cdf = vec![0.0f32; f.nnz()];
        let mut lit = vec![false; f.nrows()];
        let offsets = f.row_offsets();
        for i in 0..f.nrows() {
            let range = offsets[i]..offsets[i + 1];
            let mut total = 0.0f64;
            for ((j, v), k) in f.row(i).iter().zip(range.clone()) {
                let j = j as usize;
                let far = centre[i].distance(centre[j]) >= radius[i] + 2.0 * radius[j];
                if j != i && far && usable[j] && lum[j] > 0.0 && v > 0.0 {
                    total += (point_factor(s, i, j) * lum[j]) as f64;
                }
                cdf[k] = total as f32;
            }
            if !(total > 0.0 && total.is_finite()) {
                cdf[range].fill(0.0);
                continue;
            }
            lit[i] = true;
            let last = range
                .clone()
                .rev()
                .find(|&k| k == range.start || cdf[k] > cdf[k - 1]);
            for c in &mut cdf[range.clone()] {
                *c = (*c as f64 / total) as f32;
            }
            // Exactly 1 from the last chosen entry on.
            if let Some(last) = last {
                cdf[last..range.end].fill(1.0);
            }
        }
        PatchLights { f, cdf, lit }
    }

    /// Whether patch `i` has lights to sample.
    #[inline]
    pub fn lit(&self, i: u32) -> bool {
        self.lit[i as usize]
    }

    /// P(j | i): entry `j` of row `i`'s distribution (0 if absent).
    #[inline]
    fn probability(&self, i: usize, j: usize) -> f32 {
        let start = self.f.row_offsets()[i];
        let Some(k) = self.f.row(i).find(j as u32) else {
            return 0.0;
        };
        let lo = if k == 0 { 0.0 } else { self.cdf[start + k - 1] };
        self.cdf[start + k] - lo
    }

    /// A light for a texel of patch `i`, its ray leaving `origin`, from
    /// `u` (uniform in the unit square; `rng` for a point's rare redraw):
    /// the patch from `u.x` by the row's distribution, a texel of it by
    /// area from the rest of `u.x`, and a point uniform over the texel's
    /// surface from what is left and `u.y`. `None` at a degenerate point.
    #[inline]
    pub fn sample(
        &self,
        s: &Surfaces,
        i: u32,
        origin: Vec3,
        u: Vec2,
        rng: &mut Stream,
    ) -> Option<LightSample> {
        let i = i as usize;
        let (start, end) = (self.f.row_offsets()[i], self.f.row_offsets()[i + 1]);
        let cdf = &self.cdf[start..end];
        let k = cdf.partition_point(|&c| c <= u.x).min(cdf.len() - 1);
        let lo = if k == 0 { 0.0 } else { cdf[k - 1] };
        let p = cdf[k] - lo;
        if p <= 0.0 {
            return None;
        }
        let j = self.f.row(i).col(k) as usize;
        let mut x = ((u.x - lo) / p).clamp(0.0, 1.0) * s.patches.area[j];
        let texels = s.patches.texels_of(j);
        let mut pick = texels[texels.len() - 1];
        for &t in texels {
            let a = s.texels.area[t as usize];
            if x < a {
                pick = t;
                x /= a;
                break;
            }
            x -= a;
        }
        let jitter = Vec2::new(x.clamp(0.0, 1.0 - f32::EPSILON), u.y);
        let (y, ny) = s.sample_texel_area(pick, jitter, rng);
        let to = y - origin;
        let d2 = to.length_squared();
        let dist = d2.sqrt();
        let dir = to / dist;
        let cos_y = ny.dot(dir).abs();
        if !(dist > 0.0 && cos_y > 0.0 && dist.is_finite()) {
            return None;
        }
        Some(LightSample {
            dir,
            dist,
            patch: j as u32,
            pdf: p * d2 / (s.patches.area[j] * cos_y),
        })
    }

    /// p_n of a ray from `origin` in patch `i` whose first hit, at distance
    /// `dist` on a surface of geometric normal `ny`, landed on patch `j`.
    #[inline]
    pub fn pdf(&self, s: &Surfaces, i: u32, j: u32, dir: Vec3, dist: f32, ny: Vec3) -> f32 {
        let p = self.probability(i as usize, j as usize);
        let cos_y = ny.dot(dir).abs();
        if p <= 0.0 || cos_y <= 0.0 {
            return 0.0;
        }
        p * dist * dist / (s.patches.area[j as usize] * cos_y)
    }
}

/// The form factor from patch `i`'s centre to patch `j` as a disk of its
/// area facing along its normal: cos θᵢ cos θⱼ Aⱼ / (π d² + Aⱼ) (exact for
/// a coaxial disk, bounded near). The row's entries (ray hits) say which
/// patches i sees; their values, a few hits each, are too noisy to sample
/// by (on the Cornell box they doubled the gather's variance).
fn point_factor(s: &Surfaces, i: usize, j: usize) -> f32 {
    let p = s.patches;
    let to = p.p_ws[j] - p.p_ws[i];
    let d2 = to.length_squared();
    if d2 <= 0.0 {
        return 0.0;
    }
    let w = to / d2.sqrt();
    let (ci, cj) = (p.n_ws[i].dot(w), -p.n_ws[j].dot(w));
    ci.max(0.0) * cj.max(0.0) * p.area[j] / (std::f32::consts::PI * d2 + p.area[j])
}

/// Whether a light sample's point may come from patch `j`: no texel of it
/// has burial planes, which fold sample points (and move landings).
fn usable(s: &Surfaces) -> Vec<bool> {
    (0..s.patches.len())
        .map(|j| {
            s.patches.texels_of(j).iter().all(|&t| {
                let t = t as usize;
                !s.burial.has_planes(t) && !s.burial.split(t)
            })
        })
        .collect()
}

/// The power heuristic's weight of a strategy of density `a` against one
/// of density `b` (Veach 1997, eq. 9.13, β = 2).
#[inline]
pub fn power(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// Each patch's bounding sphere (for the near-field rule): its
/// area-weighted centroid and the farthest of its texels' centroids from
/// it, plus a texel's half diagonal (√(2·a)/2 of the largest texel area a).
fn spheres(s: &Surfaces) -> (Vec<Vec3>, Vec<f32>) {
    let (p, t) = (s.patches, s.texels);
    let centre = p.p_ws.clone();
    let radius = (0..p.len())
        .map(|i| {
            let c = centre[i];
            let (mut far, mut big) = (0.0f32, 0.0f32);
            for &x in p.texels_of(i) {
                far = far.max(t.p_ws[x as usize].distance(c));
                big = big.max(t.area[x as usize]);
            }
            far + (0.5 * big).sqrt()
        })
        .collect();
    (centre, radius)
}

/// Area-weighted outgoing radiance of each patch from its texels'.
fn patch_radiance(s: &Surfaces, radiance: &[Vec3]) -> Vec<Vec3> {
    let (p, t) = (s.patches, s.texels);
    (0..p.len())
        .map(|i| {
            let (mut sum, mut area) = (Vec3::ZERO, 0.0f32);
            for &x in p.texels_of(i) {
                let a = t.area[x as usize];
                sum += radiance[x as usize] * a;
                area += a;
            }
            if area > 0.0 {
                sum / area
            } else {
                Vec3::ZERO
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_weights_sum_to_one() {
        for &(a, b) in &[
            (1.0f32, 2.0f32),
            (0.0, 3.0),
            (5.0, 0.0),
            (1e-3, 1e3),
            (0.7, 0.7),
        ] {
            let s = power(a, b) + power(b, a);
            assert!((s - 1.0).abs() < 1e-6, "{a} {b}: {s}");
        }
        assert_eq!(power(0.0, 0.0), 0.0);
    }
}
