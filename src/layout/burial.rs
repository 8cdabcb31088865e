//! Burial planes as data: the lines where a texel's surface meets a solid
//! ([`Clip`]), each texel's exposed fraction and what folds a sample point
//! into the exposed part ([`fold`], [`Side`]). The stage that finds them is
//! [`crate::surface::burial`].

use crate::layout::texels::Texels;
use glam::Vec3;

/// One burial plane: the line where a surface crossing the texel meets
/// it. A point `x` of the texel's surface is on the texel's side when
/// `n · x ≤ k`. `n` lies in the texel's plane.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Clip {
    /// In-plane unit normal, pointing into the far side.
    pub n: Vec3,
    /// Offset.
    pub k: f32,
}

impl Clip {
    /// `x` is on the texel's side of the plane.
    #[inline]
    pub fn holds(&self, x: Vec3) -> bool {
        self.n.dot(x) <= self.k
    }
}

/// A texel's burial planes with its own plane (its largest triangle's):
/// what tells whether a point of its surface lies across a wall. The
/// planes cut the texel's plane only; points off it (on another facet of a
/// texel that wraps a corner, which may be the very wall that made the
/// plane) are never across.
#[derive(Clone, Copy, Debug, Default)]
pub struct Side<'a> {
    /// The planes.
    pub planes: &'a [Clip],
    /// The texel's plane: `ng · x = d`.
    ng: Vec3,
    d: f32,
    /// How far in front of a plane points are folded, and how far off the
    /// texel's plane a point may be and still be in it.
    pub margin: f32,
}

impl<'a> Side<'a> {
    /// The side of `planes` within the plane of normal `ng` through `p0`.
    #[inline]
    pub fn new(planes: &'a [Clip], ng: Vec3, p0: Vec3, margin: f32) -> Side<'a> {
        Side {
            planes,
            ng,
            d: ng.dot(p0),
            margin,
        }
    }

    /// Texel `t`'s side, given its largest triangle's normal `ng` and a
    /// corner `p0` of it (what [`Surfaces::texel_sampler`] has read
    /// already).
    #[inline]
    pub fn with_plane(burial: &'a Burial, t: usize, ng: Vec3, p0: Vec3) -> Side<'a> {
        if !burial.has_planes(t) {
            return Side::default();
        }
        Side::new(burial.planes_of(t), ng, p0, burial.margin[t])
    }

    /// `p` lies in the texel's plane, more than `tol` beyond one of its
    /// burial planes.
    #[inline]
    pub fn across(&self, p: Vec3, tol: f32) -> bool {
        !self.planes.is_empty()
            && (self.ng.dot(p) - self.d).abs() <= self.margin
            && self.planes.iter().any(|c| c.n.dot(p) > c.k + tol)
    }

    /// `p` moved to the texel's side ([`fold`]) where it lies in the
    /// texel's plane.
    #[inline]
    pub fn fold(&self, p: Vec3) -> Vec3 {
        if self.planes.is_empty() || (self.ng.dot(p) - self.d).abs() > self.margin {
            p
        } else {
            fold(self.planes, p, self.margin)
        }
    }
}

/// Counters of the stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BurialStats {
    /// Rays cast.
    pub rays: u64,
    /// Texels with at least one plane.
    pub clipped: u64,
    /// Texels whose centre was moved out of a solid.
    pub moved: u64,
    /// Texels with no exposed point found.
    pub buried: u64,
    /// Rays of the validity estimate (counted as the validity stage's).
    pub validity_rays: u64,
    /// Regions (see [`regions`]).
    pub regions: u64,
}

/// Every texel's burial planes and exposed fraction. [`Burial::open`] (no
/// planes anywhere) is the stage switched off.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Burial {
    /// Texel `t`'s planes are `planes[start[t]..start[t + 1]]`; empty when
    /// no texel has any.
    pub(crate) start: Vec<u32>,
    pub(crate) planes: Vec<Clip>,
    /// Exposed fraction per texel (0 for invalid texels); empty when the
    /// stage is off.
    pub(crate) exposed: Vec<f32>,
    /// Bit `t % 64` of word `t / 64`: texel `t` is split ([`Burial::split`]).
    pub(crate) split: Vec<u64>,
    /// The same for texels with planes ([`Burial::has_planes`]).
    pub(crate) clipped: Vec<u64>,
    /// Per texel, how far in front of its planes points are folded (a
    /// hundredth of a texel); empty when the stage is off.
    pub(crate) margin: Vec<f32>,
    /// Texel validity, judged from folded points ([`crate::surface::validity::validity`]);
    /// empty when the stage is off.
    pub valid: Vec<bool>,
    /// Per texel, its region ([`regions`]); empty when the stage is off.
    pub region: Vec<u32>,
    /// Per texel: every ray of the validity estimate met a back face (the
    /// final gather skips it); empty when the stage is off.
    pub(crate) enclosed: Vec<bool>,
    /// Counters.
    pub stats: BurialStats,
}

impl Burial {
    /// No planes: every texel is open.
    pub fn open() -> Self {
        Self::default()
    }

    /// Texel `t`'s planes.
    #[inline]
    pub fn planes_of(&self, t: usize) -> &[Clip] {
        if self.start.is_empty() {
            return &[];
        }
        &self.planes[self.start[t] as usize..self.start[t + 1] as usize]
    }

    /// Texel `t`'s region: the texels of its chart that it reaches without
    /// crossing a wall ([`regions`]); its chart when the stage is off. Ids
    /// are unique within an instance (compare instances too).
    #[inline]
    pub fn region(&self, texels: &Texels, t: usize) -> u32 {
        match self.region.get(t) {
            Some(&r) => r,
            None => texels.chart[t],
        }
    }

    /// How far in front of its planes texel `t`'s points are folded.
    #[inline]
    pub fn margin(&self, t: usize) -> f32 {
        self.margin.get(t).copied().unwrap_or(0.0)
    }

    /// Texel `t` has burial planes (a bit per texel, as [`Burial::split`]).
    #[inline]
    pub fn has_planes(&self, t: usize) -> bool {
        self.clipped
            .get(t / 64)
            .is_some_and(|w| w >> (t % 64) & 1 == 1)
    }

    /// Part of texel `t` lies across one of its planes, where a ray may
    /// land that came from the other side (one bit per texel: read for
    /// every ray hit, so kept small).
    #[inline]
    pub fn split(&self, t: usize) -> bool {
        self.split
            .get(t / 64)
            .is_some_and(|w| w >> (t % 64) & 1 == 1)
    }

    /// `p` lies more than texel `t`'s margin beyond one of its planes
    /// (whether or not in its plane: see [`Side::across`]).
    #[inline]
    pub fn beyond(&self, t: usize, p: Vec3) -> bool {
        let tol = self.margin(t);
        self.planes_of(t).iter().any(|c| c.n.dot(p) > c.k + tol)
    }

    /// Every ray of texel `t`'s validity estimate met a back face: it lies
    /// inside a solid.
    #[inline]
    pub fn enclosed(&self, t: usize) -> bool {
        self.enclosed.get(t).copied().unwrap_or(false)
    }

    /// The fraction of texel `t`'s area in front of its planes (0 for an
    /// invalid texel).
    #[inline]
    pub fn exposed(&self, t: usize) -> f32 {
        self.exposed.get(t).copied().unwrap_or(1.0)
    }
}

/// Moves surface point `p` to the texel's side of every plane, at least
/// `margin` in front of it: mirrored across a plane it is behind (which
/// keeps points uniform wherever the mirror image is on the texel's side),
/// else set onto the plane less the margin.
#[inline]
pub fn fold(planes: &[Clip], mut p: Vec3, margin: f32) -> Vec3 {
    for c in planes {
        let over = c.n.dot(p) - (c.k - margin);
        if over > 0.0 {
            p -= c.n * (2.0 * over);
        }
    }
    for c in planes {
        let over = c.n.dot(p) - (c.k - margin);
        if over > 0.0 {
            p -= c.n * over;
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fold_mirrors_then_clamps() {
        let c = [Clip { n: Vec3::X, k: 1.0 }];
        // Behind by 0.25: mirrored to 0.75.
        let p = fold(&c, Vec3::new(1.25, 2.0, 3.0), 0.0);
        assert!((p - Vec3::new(0.75, 2.0, 3.0)).length() < 1e-6, "{p}");
        // Exposed points stay.
        assert_eq!(
            fold(&c, Vec3::new(0.5, 0.0, 0.0), 0.0),
            Vec3::new(0.5, 0.0, 0.0)
        );
        // A strip between two planes: the mirror image is buried by the
        // other plane, so the point is set in front of it.
        let strip = [
            c[0],
            Clip {
                n: -Vec3::X,
                k: -0.9,
            },
        ];
        let p = fold(&strip, Vec3::new(1.5, 0.0, 0.0), 0.01);
        assert!(strip.iter().all(|c| c.n.dot(p) <= c.k - 0.01 + 1e-6), "{p}");
    }
}
