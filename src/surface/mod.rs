//! The surfaces light lands on, as every light stage reads them: the
//! burial planes (which part of a texel lies in open space) and the ray
//! context built over the layout and the ray caster.

pub mod burial;
pub mod validity;

use crate::layout::burial::{Burial, Side};
use crate::layout::geometry::Geometry;
use crate::layout::patches::Patches;
use crate::layout::texels::Texels;
use crate::raycast::{Hit, RayCaster};
use crate::scene::Scene;
use crate::util::sampling::{cosine_hemisphere, Net, Stream};
use glam::{Vec2, Vec3};

/// Everything a patch-to-patch query needs.
pub struct Surfaces<'a> {
    /// The scene (materials).
    pub scene: &'a Scene,
    /// World triangles.
    pub geometry: &'a Geometry,
    /// Lightmap texels.
    pub texels: &'a Texels,
    /// Patches.
    pub patches: &'a Patches,
    /// Ray caster.
    pub rays: &'a RayCaster,
    /// Burial planes: every texel sample point is folded into its texel's
    /// exposed part ([`crate::surface::burial`]).
    pub burial: &'a Burial,
}

/// What a ray found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Landing {
    /// The front (or a double-sided back) of this texel.
    Texel(u32),
    /// The back of a one-sided surface.
    BackFace,
    /// A surface that has no lightmap texel at that point.
    Unmapped,
    /// Nothing: the ray left the scene.
    Escaped,
}

impl Surfaces<'_> {
    /// A uniformly distributed point on patch `i` (by area), with the
    /// geometric normal there: a texel picked by area from `u`
    /// ([`Surfaces::pick_texel`]), then a point in its square from
    /// `jitter`, kept if it lies on the texel's main triangle (else the
    /// texel's centroid).
    pub fn sample_patch(&self, i: usize, u: f32, jitter: Vec2) -> (Vec3, Vec3) {
        let texels = self.patches.texels_of(i);
        self.sample_texel(texels[self.pick_texel(i, u)], jitter)
    }

    /// The texel of patch `i` (its index in the patch's texels) that `u`
    /// picks by area. Texels are picked by exposed area
    /// ([`Burial::exposed`]), so no point starts inside a solid while the
    /// patch has an exposed part.
    pub fn pick_texel(&self, i: usize, u: f32) -> usize {
        let texels = self.patches.texels_of(i);
        let (area, open) = (self.patches.area[i], self.patches.exposed_area[i]);
        let weigh = open < area && open > 0.0;
        let mut target = u * if weigh { open } else { area };
        for (k, &t) in texels.iter().enumerate() {
            let a = self.texels.area[t as usize];
            target -= if weigh {
                a * self.burial.exposed(t as usize)
            } else {
                a
            };
            if target <= 0.0 {
                return k;
            }
        }
        texels.len() - 1
    }

    /// Patch `i` has no exposed area: every texel of it lies inside or
    /// under geometry ([`crate::surface::burial`]). Nothing reaches it, so its row
    /// of F is empty: its rays would start inside a solid and carry light
    /// from one side of a wall to the other.
    pub fn patch_buried(&self, i: usize) -> bool {
        !self.burial.valid.is_empty() && self.patches.exposed_area[i] <= 0.0
    }

    /// A point of texel `t` (see [`Surfaces::sample_patch`]) and its normal.
    pub fn sample_texel(&self, t: u32, jitter: Vec2) -> (Vec3, Vec3) {
        self.texel_sampler(t).sample(jitter)
    }

    /// A point uniformly distributed over texel `t`'s surface by world
    /// area, over all of its pieces (one per covering triangle), and the
    /// normal there: the texel's exact mean is the mean of a function over
    /// these points. (`sample_texel` keeps to the texel's largest triangle,
    /// clamping points outside it onto it, which is what the bake's rays
    /// need; the path-traced reference needs the mean itself.) `jitter`
    /// picks the piece by area (its x) and the point (both, remapped); a
    /// point outside the piece's triangle is redrawn from `rng` (up to 64
    /// times, then the piece's centroid).
    pub fn sample_texel_area(&self, t: u32, jitter: Vec2, rng: &mut Stream) -> (Vec3, Vec3) {
        self.texel_sampler(t).sample_area(jitter, rng)
    }

    /// Texel `t`'s sampling constants, for drawing many points from it
    /// ([`TexelSampler::sample`] gives exactly [`Surfaces::sample_texel`]'s
    /// points, without re-reading the triangle for each;
    /// [`TexelSampler::sample_area`] [`Surfaces::sample_texel_area`]'s).
    pub fn texel_sampler(&self, t: u32) -> TexelSampler<'_> {
        let t = t as usize;
        let tri = self.texels.triangle[t];
        let [x, y] = self.texels.xy[t];
        let uv = &self.geometry.uv_lm[tri as usize];
        let ng = self.geometry.ng_ws[tri as usize];
        let pieces = self.texels.pieces_of(t);
        let p = self.geometry.p_ws[tri as usize];
        TexelSampler {
            geometry: self.geometry,
            side: Side::with_plane(self.burial, t, ng, p[0]),
            pieces,
            total: pieces.iter().map(|p| p.area).sum(),
            tri,
            corner: Vec2::new(x as f32, y as f32),
            uv0: uv[0],
            uv_e1: uv[1] - uv[0],
            uv_e2: uv[2] - uv[0],
            uv_det: (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]),
            p,
            ng,
            frame: crate::util::sampling::frame(ng),
        }
    }

    /// Where a ray from `origin` along `dir` lands.
    pub fn trace(&self, origin: Vec3, dir: Vec3) -> (Landing, Option<Hit>) {
        match self.rays.closest_hit(origin, dir, f32::INFINITY) {
            Some(hit) => (self.land(hit.tri, hit.u, hit.v, dir), Some(hit)),
            None => (Landing::Escaped, None),
        }
    }

    /// Whether triangle `tri` is seen from its front from `eye` (or is
    /// double-sided): [`Surfaces::land`]'s side test, the same for every
    /// point of the triangle.
    #[inline]
    pub fn seen_from(&self, tri: u32, eye: Vec3) -> bool {
        let g = self.geometry;
        let t = tri as usize;
        g.ng_ws[t].dot(g.p_ws[t][0] - eye) < 0.0
            || self.scene.materials[g.material[t] as usize].double_sided
    }

    /// Whether a ray along `dir` meets triangle `tri` from behind and it
    /// is one-sided: [`Landing::BackFace`], told without the texel lookup.
    #[inline]
    pub fn back_face(&self, tri: u32, dir: Vec3) -> bool {
        let (g, t) = (self.geometry, tri as usize);
        let front = g.ng_ws[t].dot(dir) < 0.0;
        !front && !self.scene.materials[g.material[t] as usize].double_sided
    }

    /// Whether the ray from `origin` along `dir` first meets a one-sided
    /// surface from behind ([`Surfaces::trace`]'s [`Landing::BackFace`],
    /// without landing the hit on a texel).
    #[inline]
    pub fn meets_back_face(&self, origin: Vec3, dir: Vec3) -> bool {
        self.rays
            .closest_hit(origin, dir, f32::INFINITY)
            .is_some_and(|h| self.back_face(h.tri, dir))
    }

    /// The texel at barycentrics (u, v) of triangle `tri`, reached along `dir`.
    pub fn land(&self, tri: u32, u: f32, v: f32, dir: Vec3) -> Landing {
        if self.back_face(tri, dir) {
            return Landing::BackFace;
        }
        let (page, uv_lm, instance, chart) = self.lookup_query(tri, u, v);
        match self.texels.lookup(page, uv_lm, instance, chart) {
            Some(texel) => self.landed(texel, tri, u, v),
            None => Landing::Unmapped,
        }
    }

    /// What [`Texels::lookup`] needs for barycentrics (u, v) of triangle
    /// `tri`: its page, the lightmap point, its instance and chart.
    #[inline(always)]
    fn lookup_query(&self, tri: u32, u: f32, v: f32) -> (u32, Vec2, u32, u32) {
        let (g, t) = (self.geometry, tri as usize);
        (g.page[t], g.uv_lm_at(tri, u, v), g.instance[t], g.chart[t])
    }

    /// The landing of a hit at (u, v) of `tri` that lookup found in
    /// `texel`: the texel, or where it is split by its burial planes
    /// ([`Burial::split`]), the texel on the hit's side.
    #[inline(always)]
    fn landed(&self, texel: u32, tri: u32, u: f32, v: f32) -> Landing {
        if self.burial.split(texel as usize) {
            self.beside(texel, self.geometry.point(tri, u, v))
        } else {
            Landing::Texel(texel)
        }
    }

    /// [`Surfaces::land`] of each of `hits` (`dir(i)` the direction of
    /// hit `i`'s ray), in order, with the same answers. In three passes
    /// over up to 16 hits: the triangles' records (side, lightmap point,
    /// page, chart), then the texel map's entries, then the split texels.
    /// Each pass's loads are independent of one another, so their cache
    /// misses overlap: landing one hit at a time waits for a chain of
    /// three (triangle, texel map, texel), and that was 14 % of Sponza's
    /// bake (`perf`).
    pub fn land_many(
        &self,
        hits: &[Option<Hit>],
        dir: impl Fn(usize) -> Vec3,
        out: &mut [Landing],
    ) {
        const BATCH: usize = 16;
        for (c, (hits, out)) in hits.chunks(BATCH).zip(out.chunks_mut(BATCH)).enumerate() {
            let mut queries = [(0u32, Vec2::ZERO, 0u32, 0u32); BATCH];
            let mut asked = [0usize; BATCH];
            let mut n = 0;
            for (i, (hit, o)) in hits.iter().zip(out.iter_mut()).enumerate() {
                let Some(h) = hit else {
                    *o = Landing::Escaped;
                    continue;
                };
                *o = if self.back_face(h.tri, dir(c * BATCH + i)) {
                    Landing::BackFace
                } else {
                    queries[n] = self.lookup_query(h.tri, h.u, h.v);
                    asked[n] = i;
                    n += 1;
                    Landing::Unmapped
                };
            }
            let mut found = [None; BATCH];
            self.texels.lookup_batch(&queries[..n], &mut found[..n]);
            for (&i, texel) in asked[..n].iter().zip(found) {
                let Some(texel) = texel else {
                    continue;
                };
                let h = hits[i].expect("asked only for hits");
                out[i] = self.landed(texel, h.tri, h.u, h.v);
            }
        }
    }

    /// The texel of a hit at `p` that lookup found in `texel`, a texel
    /// split by its burial planes ([`Burial::split`]): itself where `p` is on its exposed side, else
    /// the nearest of its 8 neighbours in its chart that has `p` on its
    /// exposed side (the hit is on the part of `texel` across a wall, which
    /// holds the other side's light); `texel` itself if none does (planes
    /// of a surface that does not close off the texel, a thin pole or a
    /// curved face: a ray from the open side reached the point). Reading
    /// nothing there instead lost 1.5 % of Sponza's form-factor rays and
    /// read its arcades 10 % dark.
    #[inline(never)]
    fn beside(&self, texel: u32, p: Vec3) -> Landing {
        let tx = self.texels;
        let t = texel as usize;
        // Most hits on such texels are on their side: the planes alone
        // tell, before the texel's own plane is read.
        if !self.burial.beyond(t, p) {
            return Landing::Texel(texel);
        }
        let side = self.side(t);
        if !side.across(p, side.margin) {
            return Landing::Texel(texel);
        }
        // `p` lies in `texel`'s plane; a neighbour of the same chart shares
        // it where it matters, so its planes alone decide.
        let [x, y] = tx.xy[t];
        let mut best: Option<(f32, u32)> = None;
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let Some(u) = tx.at(tx.page[t], x as i64 + dx, y as i64 + dy) else {
                    continue;
                };
                let ui = u as usize;
                if u == texel
                    || tx.instance[ui] != tx.instance[t]
                    || tx.chart[ui] != tx.chart[t]
                    || self.burial.beyond(ui, p)
                {
                    continue;
                }
                let d = tx.p_ws[ui].distance_squared(p);
                if best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, u));
                }
            }
        }
        best.map_or(Landing::Texel(texel), |(_, u)| Landing::Texel(u))
    }
}

/// One texel's sampling constants ([`Surfaces::texel_sampler`]): its main
/// triangle in the lightmap and in the world, and the frame of its normal.
#[derive(Clone, Copy, Debug)]
pub struct TexelSampler<'a> {
    geometry: &'a Geometry,
    /// The texel's burial planes, which sample points are folded behind.
    side: Side<'a>,
    pieces: &'a [crate::layout::texels::Piece],
    /// Σ of the pieces' areas.
    total: f32,
    /// The largest triangle.
    tri: u32,
    corner: Vec2,
    uv0: Vec2,
    uv_e1: Vec2,
    uv_e2: Vec2,
    uv_det: f32,
    p: [Vec3; 3],
    /// Geometric normal (world, unit).
    pub ng: Vec3,
    frame: (Vec3, Vec3),
}

impl TexelSampler<'_> {
    /// A point uniformly distributed over the texel's surface by world
    /// area, over all of its pieces, and the normal there (see
    /// [`Surfaces::sample_texel_area`]).
    #[inline]
    pub fn sample_area(&self, jitter: Vec2, rng: &mut Stream) -> (Vec3, Vec3) {
        let (p, ng) = self.sample_pieces(jitter, rng);
        (self.fold(p), ng)
    }

    /// A point folded into the texel's exposed part ([`crate::layout::burial::fold`]).
    #[inline]
    fn fold(&self, p: Vec3) -> Vec3 {
        self.side.fold(p)
    }

    /// [`TexelSampler::sample_area`]'s point before folding.
    fn sample_pieces(&self, jitter: Vec2, rng: &mut Stream) -> (Vec3, Vec3) {
        if self.pieces.is_empty() || !(self.total > 0.0 && self.total.is_finite()) {
            return self.sample_unfolded(jitter);
        }
        // The piece, by area, from jitter.x (remapped to stay uniform).
        let (mut tri, mut jx, mut centroid) = (self.tri, jitter.x, None);
        if self.pieces.len() > 1 || self.pieces[0].tri != self.tri {
            let mut x = jitter.x * self.total;
            let mut piece = self.pieces[self.pieces.len() - 1];
            jx = 0.5;
            for p in self.pieces {
                if x < p.area {
                    piece = *p;
                    jx = (x / p.area).clamp(0.0, 1.0 - f32::EPSILON);
                    break;
                }
                x -= p.area;
            }
            tri = piece.tri;
            centroid = Some((piece.u, piece.v));
        }
        let g = self.geometry;
        let (uv0, e1, e2, det, p, ng) = if tri == self.tri {
            (
                self.uv0,
                self.uv_e1,
                self.uv_e2,
                self.uv_det,
                self.p,
                self.ng,
            )
        } else {
            let uv = &g.uv_lm[tri as usize];
            let (e1, e2) = (uv[1] - uv[0], uv[2] - uv[0]);
            (
                uv[0],
                e1,
                e2,
                e1.perp_dot(e2),
                g.p_ws[tri as usize],
                g.ng_ws[tri as usize],
            )
        };
        let mut q = self.corner + Vec2::new(jx, jitter.y);
        for _ in 0..64 {
            let w1 = (q - uv0).perp_dot(e2) / det;
            let w2 = e1.perp_dot(q - uv0) / det;
            let w = glam::Vec3::new(1.0 - w1 - w2, w1, w2);
            if w.min_element() >= 0.0 {
                // A hair inside the edges, as `sample`.
                let w = w.max(glam::Vec3::splat(1e-4));
                let w = w / w.element_sum();
                let (u, v) = (w.y, w.z);
                return (p[0] * (1.0 - u - v) + p[1] * u + p[2] * v, ng);
            }
            // Outside the piece (a texel it covers partly): redraw.
            q = self.corner + rng.next_vec2();
        }
        // A sliver the redraws keep missing: its centroid, kept a hair
        // inside the edges too (a point on a corner sends rays along the
        // neighbouring faces).
        let (u, v) = centroid.unwrap_or_else(|| {
            let piece = self
                .pieces
                .iter()
                .find(|x| x.tri == tri)
                .copied()
                .unwrap_or_default();
            (piece.u, piece.v)
        });
        let w = glam::Vec3::new(1.0 - u - v, u, v).max(glam::Vec3::splat(1e-4));
        let w = w / w.element_sum();
        let (u, v) = (w.y, w.z);
        (p[0] * (1.0 - u - v) + p[1] * u + p[2] * v, ng)
    }

    /// The surface point at `jitter` ∈ [0, 1)² of the texel, and the normal.
    /// Points outside the triangle (texels it covers partly) are clamped
    /// onto it, and every point is kept a hair inside its edges: a ray
    /// leaving exactly from an edge that meets another face can slip
    /// through the crack between them. (The arithmetic of
    /// [`crate::layout::texels::barycentric`] and [`crate::layout::geometry::Geometry::point`].)
    /// The point is then folded into the texel's exposed part.
    #[inline]
    pub fn sample(&self, jitter: Vec2) -> (Vec3, Vec3) {
        let (p, ng) = self.sample_unfolded(jitter);
        (self.fold(p), ng)
    }

    /// [`TexelSampler::sample`]'s point before folding.
    #[inline]
    fn sample_unfolded(&self, jitter: Vec2) -> (Vec3, Vec3) {
        let q = self.corner + jitter;
        let w1 = (q - self.uv0).perp_dot(self.uv_e2) / self.uv_det;
        let w2 = self.uv_e1.perp_dot(q - self.uv0) / self.uv_det;
        let w = glam::Vec3::new(1.0 - w1 - w2, w1, w2).max(glam::Vec3::splat(1e-4));
        let w = w / w.element_sum();
        let (u, v) = (w.y, w.z);
        let p = self.p[0] * (1.0 - u - v) + self.p[1] * u + self.p[2] * v;
        (p, self.ng)
    }

    /// A local (+Z up) direction in the world, around the texel's normal
    /// ([`crate::util::sampling::to_world`]).
    #[inline]
    pub fn to_world(self, local: Vec3) -> Vec3 {
        let (t, b) = self.frame;
        t * local.x + b * local.y + self.ng * local.z
    }
}

impl<'a> Surfaces<'a> {
    /// Texel `t`'s burial side (its planes within its largest triangle's
    /// plane).
    pub fn side(&self, t: usize) -> Side<'a> {
        let tri = self.texels.triangle[t] as usize;
        Side::with_plane(
            self.burial,
            t,
            self.geometry.ng_ws[tri],
            self.geometry.p_ws[tri][0],
        )
    }
}

/// Ray `k` from a texel: a point of the position net and a
/// cosine-weighted direction of the direction net (two independently
/// scrambled (0, 2)-sequences, [`Net`], so that every power-of-two prefix
/// of the rays is stratified in position and in direction, and the
/// adaptive gather may stop there). Returns (point, normal, direction).
#[inline(always)]
pub(crate) fn texel_ray(sampler: &TexelSampler, k: u32, nets: &(Net, Net)) -> (Vec3, Vec3, Vec3) {
    let (p, ng) = sampler.sample(nets.0.point(k));
    let dir = sampler.to_world(cosine_hemisphere(nets.1.point(k)));
    (p, ng, dir)
}

/// A texel's two nets (position, direction) for `purpose`.
pub(crate) fn texel_nets(seed: u64, purpose: u64, t: usize) -> (Net, Net) {
    let mut rng = Stream::new(seed, purpose, t as u64);
    (Net::shuffled(&mut rng), Net::new(&mut rng))
}
