//! Burial planes: which part of each texel lies in open space, so that no
//! ray of the bake ever starts inside a solid.
//!
//! Game levels run floors under walls and columns, and join rooms back to
//! back. A texel that lies partly under a wall has sample points inside it,
//! and a ray from there rises inside the wall to whatever closes it: the
//! ceiling strip over the wall, half of which belongs to the room on the
//! other side. That is light through a wall (issue #19: 8.7e-4 of the lit
//! room's floor light in the sealed room with a 0.2 m wall).
//!
//! This stage is what Bakery calls adjusting sample positions. From each
//! texel's centre, lifted a hair off its surface, eight rays run along the
//! surface for one texel width. Whatever they meet crosses the texel: the
//! surface there is a *burial plane*, the line where the surface met
//! ([`Clip`]), and the part of the texel beyond it is on the other side of
//! a wall, under a column, or through a back-to-back partition. When the
//! centre itself is inside a solid (the rays meet back faces, and most of
//! a few hemisphere rays do too), it is moved out through the nearest back
//! face first. Every sample point of the texel (form factors, direct light,
//! validity, final gather, the references) is then folded into the exposed
//! part ([`fold`]) before a ray leaves it.
//!
//! The stage also gives each texel's *exposed fraction*: the share of its
//! area in front of its planes. The report's per-instance `mean` weighs each
//! texel by it: buried area receives nothing.

use crate::form_factors::raycast::Surfaces;
use crate::sampling::{cosine_hemisphere, stratified, to_world, Stream};
use crate::texels::Texels;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Stream purpose id of the burial test's hemisphere rays and area points.
const PURPOSE: u64 = 12;

/// Rays along the surface per texel.
const TANGENT_RAYS: u32 = 8;

/// Hemisphere rays that judge whether a centre is inside a solid.
const HEMISPHERE_RAYS: u32 = 8;

/// Times a buried centre may be moved out through a back face.
const MOVES: usize = 2;

/// Points per texel that estimate its exposed fraction.
const AREA_POINTS: u32 = 16;

/// Height of the tangent rays over the surface and how far in front of a
/// plane a folded point stays, in texel widths.
const LIFT: f32 = 0.01;

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

    /// Texel `t`'s side.
    pub fn of(s: &Surfaces<'a>, t: usize) -> Side<'a> {
        let tri = s.texels.triangle[t] as usize;
        Side::with_plane(s.burial, t, s.geometry.ng_ws[tri], s.geometry.p_ws[tri][0])
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
    start: Vec<u32>,
    planes: Vec<Clip>,
    /// Exposed fraction per texel (0 for invalid texels); empty when the
    /// stage is off.
    exposed: Vec<f32>,
    /// Bit `t % 64` of word `t / 64`: texel `t` is split ([`Burial::split`]).
    split: Vec<u64>,
    /// The same for texels with planes ([`Burial::has_planes`]).
    clipped: Vec<u64>,
    /// Per texel, how far in front of its planes points are folded (a
    /// hundredth of a texel); empty when the stage is off.
    margin: Vec<f32>,
    /// Texel validity, judged from folded points ([`crate::gather::validity`]);
    /// empty when the stage is off.
    pub valid: Vec<bool>,
    /// Per texel, its region ([`regions`]); empty when the stage is off.
    pub region: Vec<u32>,
    /// Per texel: every ray of the validity estimate met a back face (the
    /// final gather skips it); empty when the stage is off.
    enclosed: Vec<bool>,
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

/// A texel's width in metres: √(world area / lightmap area) of its main
/// triangle (lightmap UVs are in texels).
fn texel_width(s: &Surfaces, t: usize) -> f32 {
    let g = s.geometry;
    let tri = s.texels.triangle[t] as usize;
    let p = &g.p_ws[tri];
    let uv = &g.uv_lm[tri];
    let world = (p[1] - p[0]).cross(p[2] - p[0]).length();
    let lm = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).abs();
    if lm > 0.0 && world > 0.0 {
        (world / lm).sqrt()
    } else {
        0.0
    }
}

/// What one ray along the surface met: its distance, the plane it gives,
/// and whether it was a back face.
struct Crossing {
    t: f32,
    dir: Vec3,
    clip: Clip,
    back: bool,
}

/// The eight rays along the surface from `o`, reaching `reach`. Only
/// surfaces at more than 30° to the texel's count: a wall, a column, a
/// step; not the texel's own surface curving up (the inside of a sphere)
/// or a gentle ramp.
fn crossings(s: &Surfaces, o: Vec3, ng: Vec3, reach: f32) -> Vec<Crossing> {
    let (tx, ty) = crate::sampling::frame(ng);
    let mut out = Vec::new();
    for k in 0..TANGENT_RAYS {
        let a = std::f32::consts::TAU * k as f32 / TANGENT_RAYS as f32;
        let dir = tx * a.cos() + ty * a.sin();
        let Some(hit) = s.rays.closest_hit(o, dir, reach) else {
            continue;
        };
        let tri = hit.tri as usize;
        let nh = s.geometry.ng_ws[tri];
        let back =
            nh.dot(dir) > 0.0 && !s.scene.materials[s.geometry.material[tri] as usize].double_sided;
        // The plane of the surface met, within the texel's plane: exact for
        // a planar wall at any angle; the ray's own direction where the
        // surface met lies nearly along the texel's.
        // The plane of the surface met, within the texel's plane: exact
        // for a planar wall at any angle.
        let inplane = nh - ng * nh.dot(ng);
        if inplane.length_squared() <= 0.25 {
            continue;
        }
        let n = inplane.normalize();
        let n = if n.dot(dir) < 0.0 { -n } else { n };
        let q = o + dir * hit.t;
        out.push(Crossing {
            t: hit.t,
            dir,
            clip: Clip { n, k: n.dot(q) },
            back,
        });
    }
    out
}

/// More than half of `HEMISPHERE_RAYS` cosine-distributed rays from `o`
/// meet back faces: `o` is inside a solid.
fn inside(s: &Surfaces, o: Vec3, ng: Vec3, rng: &mut Stream) -> bool {
    let mut back = 0;
    for k in 0..HEMISPHERE_RAYS {
        let dir = to_world(
            cosine_hemisphere(stratified(k, HEMISPHERE_RAYS, rng.next_vec2())),
            ng,
        );
        if s.meets_back_face(o, dir) {
            back += 1;
        }
    }
    back * 2 > HEMISPHERE_RAYS
}

/// One texel's planes, exposed fraction, rays cast, and whether its centre
/// moved.
fn texel(s: &Surfaces, t: usize, seed: u64) -> TexelBurial {
    let width = texel_width(s, t);
    if width <= 0.0 || !width.is_finite() {
        return TexelBurial::default();
    }
    let sampler = s.texel_sampler(t as u32);
    let ng = sampler.ng;
    let lift = LIFT * width;
    let (centre, _) = sampler.sample(Vec2::splat(0.5));
    let mut o = centre + ng * lift;
    let mut rng = Stream::new(seed, PURPOSE, t as u64);
    let mut rays = 0u64;
    let mut moved = false;
    let mut found = crossings(s, o, ng, width);
    rays += TANGENT_RAYS as u64;
    for _ in 0..MOVES {
        let Some(exit) = found
            .iter()
            .filter(|c| c.back)
            .min_by(|a, b| a.t.total_cmp(&b.t))
        else {
            break;
        };
        // A back face along the surface: the centre is inside a solid, or
        // beside open one-sided geometry seen from behind (then most of its
        // hemisphere is open, and it stays).
        rays += HEMISPHERE_RAYS as u64;
        if !inside(s, o, ng, &mut rng) {
            break;
        }
        o += exit.dir * (exit.t + 2.0 * lift);
        moved = true;
        found = crossings(s, o, ng, width);
        rays += TANGENT_RAYS as u64;
    }
    let planes: Vec<Clip> = found.iter().map(|c| c.clip).collect();
    if planes.is_empty() {
        return TexelBurial {
            planes,
            exposed: 1.0,
            margin: lift,
            rays,
            moved,
        };
    }
    let tri = s.texels.triangle[t] as usize;
    let side = Side::new(&planes, ng, s.geometry.p_ws[tri][0], lift);
    // Points of the texel's square on its largest triangle's plane (the
    // fast sampler's, clamped onto the triangle): the planes cut that plane.
    let mut exposed = 0u32;
    for k in 0..AREA_POINTS {
        let jitter = stratified(k, AREA_POINTS, rng.next_vec2());
        let (p, _) = sampler.sample(jitter);
        if !side.across(p, 0.0) {
            exposed += 1;
        }
    }
    TexelBurial {
        planes,
        exposed: exposed as f32 / AREA_POINTS as f32,
        margin: lift,
        rays,
        moved,
    }
}

/// One texel's part of [`Burial`].
struct TexelBurial {
    planes: Vec<Clip>,
    exposed: f32,
    margin: f32,
    rays: u64,
    moved: bool,
}

impl Default for TexelBurial {
    fn default() -> Self {
        TexelBurial {
            planes: Vec::new(),
            exposed: 1.0,
            margin: 0.0,
            rays: 0,
            moved: false,
        }
    }
}

/// Every texel's burial planes and validity (see the module
/// documentation). `s` is read for its geometry, texels and ray caster;
/// its own burial is not used. The validity estimate
/// ([`crate::gather::validity`], `validity_rays` per texel) casts from
/// points folded by the new planes; invalid texels (inside a solid) count
/// as not exposed at all; `tolerance` is the back-face tolerance.
pub fn compute(s: &Surfaces, seed: u64, validity_rays: u32, tolerance: f32) -> Burial {
    let mut burial = planes(s, seed);
    let folded = Surfaces {
        burial: &burial,
        ..*s
    };
    let judged = crate::gather::validity(&folded, validity_rays, seed, tolerance);
    let (valid, rays) = (judged.valid, judged.rays);
    burial.enclosed = judged.enclosed;
    for (e, &v) in burial.exposed.iter_mut().zip(&valid) {
        if !v {
            *e = 0.0;
        }
    }
    burial.stats.buried = burial.exposed.iter().filter(|&&e| e == 0.0).count() as u64;
    burial.stats.validity_rays = rays;
    burial.valid = valid;
    burial.region = regions(s, &burial);
    burial.stats.regions = {
        let mut r = burial.region.clone();
        r.sort_unstable();
        r.dedup();
        r.len() as u64
    };
    burial
}

/// Every texel's region: valid texels of one chart joined wherever two
/// neighbours (8-connected in the lightmap) lie on the same side of each
/// other's burial planes. A wall standing on a floor, or a partition
/// between two rooms modelled as one mesh, cuts the floor's chart into
/// regions; patches, their interpolation and the denoiser never mix two
/// regions, so no light crosses the wall through them. Invalid texels
/// (inside solids) form one region per chart. Ids: the smallest texel of a
/// region, or `texels.len()` + the chart's owner id for the invalid ones.
fn regions(s: &Surfaces, burial: &Burial) -> Vec<u32> {
    let texels = s.texels;
    let n = texels.len();
    // Each texel's side, and its centroid folded to it.
    let with = Surfaces { burial, ..*s };
    let sides: Vec<Side> = (0..n).map(|t| Side::of(&with, t)).collect();
    let rep: Vec<Vec3> = (0..n)
        .into_par_iter()
        .map(|t| sides[t].fold(texels.p_ws[t]))
        .collect();
    let in_front = |t: usize, u: usize| !sides[t].across(rep[u], 0.0);
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn root(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            let up = parent[parent[x as usize] as usize];
            parent[x as usize] = up;
            x = up;
        }
        x
    }
    for t in 0..n {
        if !burial.valid[t] {
            continue;
        }
        let [x, y] = texels.xy[t];
        for (dx, dy) in [(1i64, 0i64), (-1, 1), (0, 1), (1, 1)] {
            let Some(u) = texels.at(texels.page[t], x as i64 + dx, y as i64 + dy) else {
                continue;
            };
            let u = u as usize;
            if burial.valid[u]
                && texels.instance[u] == texels.instance[t]
                && texels.chart[u] == texels.chart[t]
                && in_front(t, u)
                && in_front(u, t)
            {
                let (a, b) = (root(&mut parent, t as u32), root(&mut parent, u as u32));
                // The smaller id becomes the root: ids do not depend on
                // the order of the unions.
                let (lo, hi) = (a.min(b), a.max(b));
                parent[hi as usize] = lo;
            }
        }
    }
    (0..n)
        .map(|t| {
            if burial.valid[t] {
                root(&mut parent, t as u32)
            } else {
                (n as u32).wrapping_add(texels.owner(texels.instance[t], texels.chart[t]))
            }
        })
        .collect()
}

/// Every texel's planes and exposed fraction.
fn planes(s: &Surfaces, seed: u64) -> Burial {
    let n = s.texels.len();
    let chunk = 1024;
    let parts: Vec<Vec<TexelBurial>> = (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            (c * chunk..((c + 1) * chunk).min(n))
                .map(|t| texel(s, t, seed))
                .collect()
        })
        .collect();
    let mut burial = Burial {
        start: Vec::with_capacity(n + 1),
        planes: Vec::new(),
        exposed: Vec::with_capacity(n),
        margin: Vec::with_capacity(n),
        split: vec![0; n.div_ceil(64)],
        clipped: vec![0; n.div_ceil(64)],
        valid: Vec::new(),
        region: Vec::new(),
        enclosed: Vec::new(),
        stats: BurialStats::default(),
    };
    burial.start.push(0);
    for (t, x) in parts.into_iter().flatten().enumerate() {
        if !x.planes.is_empty() {
            burial.clipped[t / 64] |= 1 << (t % 64);
            if x.exposed < 1.0 {
                burial.split[t / 64] |= 1 << (t % 64);
            }
        }
        let st = &mut burial.stats;
        st.rays += x.rays;
        st.clipped += !x.planes.is_empty() as u64;
        st.moved += x.moved as u64;
        burial.planes.extend(x.planes);
        burial.start.push(burial.planes.len() as u32);
        burial.exposed.push(x.exposed);
        burial.margin.push(x.margin);
    }
    burial
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
