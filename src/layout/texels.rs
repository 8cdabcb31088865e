//! Lightmap texels: every triangle rasterised into the atlas
//! *exactly*: each texel square is clipped against the triangle
//! (Sutherland–Hodgman), so a texel gets the world area it really covers,
//! the area-weighted centroid as its position and the covering material's
//! albedo and emission. This is conservative (thin triangles still get every
//! texel they touch) and conserves area: Σ texel area = Σ triangle area.

use crate::layout::atlas::Atlas;
use crate::layout::geometry::Geometry;
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Marks an empty texel in [`Texels::index`].
pub const EMPTY: u32 = u32::MAX;

/// An empty entry of [`Texels::index`].
pub const EMPTY_ENTRY: u64 = u64::MAX;

/// The part of a texel one triangle covers: where a texel spans a curve or
/// a fold, its pieces face different ways (and its world centroid lies off
/// the surface), so light that depends on the normal is evaluated per piece.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Piece {
    /// World triangle.
    pub tri: u32,
    /// Barycentrics (of vertices 1 and 2) of the piece's centroid: a point
    /// on the surface, inside the piece.
    pub u: f32,
    /// See `u`.
    pub v: f32,
    /// Covered world area (m²).
    pub area: f32,
}

/// Covered lightmap texels (struct of arrays, indexed by texel id).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Texels {
    /// Atlas page.
    pub page: Vec<u32>,
    /// Column and row in the page.
    pub xy: Vec<[u32; 2]>,
    /// Instance covering the texel.
    pub instance: Vec<u32>,
    /// Chart (per mesh) covering the texel.
    pub chart: Vec<u32>,
    /// Triangle covering most of the texel.
    pub triangle: Vec<u32>,
    /// Area-weighted centroid (world). Off the surface where the texel
    /// covers a fold or a curve; see [`Texels::pieces`].
    pub p_ws: Vec<Vec3>,
    /// Area-weighted geometric normal (world, unit).
    pub n_ws: Vec<Vec3>,
    /// Covered world area (m²).
    pub area: Vec<f32>,
    /// The texel's pieces (one per triangle covering it) of texel `t` are
    /// `pieces[piece_start[t]..piece_start[t + 1]]`.
    pub piece_start: Vec<u32>,
    /// Every texel's pieces, in texel order.
    pub pieces: Vec<Piece>,
    /// Area-weighted albedo ρ.
    pub albedo: Vec<Vec3>,
    /// Area-weighted emitted radiance.
    pub emission: Vec<Vec3>,
    /// Per page, `width × height` entries (row-major): the texel's id in
    /// the low 32 bits and its owner (see [`Texels::owner`]) in the high
    /// ones, [`EMPTY_ENTRY`] where none. One load tells a hit's lookup
    /// both which texel it is and whether it belongs to the hit's surface:
    /// a gather hit's lookup used to read three scattered arrays (14 % of a
    /// bake's time on the generated level, `perf`).
    pub index: Vec<Vec<u64>>,
    /// Per instance, the owner id of its chart 0: (instance, chart) is owner
    /// `owner_base[instance] + chart`, unique over the scene.
    pub owner_base: Vec<u32>,
    /// Page width.
    pub width: u32,
    /// Page height.
    pub height: u32,
    /// Triangles that got no texel (degenerate in UV space).
    pub unmapped_triangles: u64,
    /// Texels touched by two different charts (0 for a valid atlas: charts
    /// are `2 × padding` apart).
    pub chart_overlaps: u64,
}

impl Texels {
    /// Number of texels.
    pub fn len(&self) -> usize {
        self.page.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.page.is_empty()
    }

    /// The pieces of texel `t`.
    pub fn pieces_of(&self, t: usize) -> &[Piece] {
        &self.pieces[self.piece_start[t] as usize..self.piece_start[t + 1] as usize]
    }

    /// The texel at integer `(x, y)` of `page`, if covered.
    pub fn at(&self, page: u32, x: i64, y: i64) -> Option<u32> {
        self.entry(page, x, y).map(|(id, _)| id)
    }

    /// The texel at integer `(x, y)` of `page` and its owner, if covered.
    #[inline]
    fn entry(&self, page: u32, x: i64, y: i64) -> Option<(u32, u32)> {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return None;
        }
        let e = self.index[page as usize][(y as u32 * self.width + x as u32) as usize];
        (e != EMPTY_ENTRY).then_some((e as u32, (e >> 32) as u32))
    }

    /// The owner id of (`instance`, `chart`): unique over the scene.
    #[inline]
    pub fn owner(&self, instance: u32, chart: u32) -> u32 {
        self.owner_base[instance as usize].wrapping_add(chart)
    }

    /// The texel of cell (`x`, `y`) on `page` where it belongs to the
    /// surface (`instance`, `chart`): [`Texels::lookup`]'s answer for every
    /// point of the cell, when it is this one (else lookup looks around).
    #[inline]
    pub fn cell(&self, page: u32, x: i64, y: i64, instance: u32, chart: u32) -> Option<u32> {
        if chart == u32::MAX {
            return None;
        }
        let owner = self.owner(instance, chart);
        self.entry(page, x, y)
            .and_then(|(t, o)| (o == owner).then_some(t))
    }

    /// The texel holding lightmap point `uv_lm` on `page` for a surface of
    /// (`instance`, `chart`); when rounding puts it just outside its chart,
    /// the nearest texel of that chart in the 3×3 neighbourhood.
    pub fn lookup(&self, page: u32, uv_lm: Vec2, instance: u32, chart: u32) -> Option<u32> {
        if chart == u32::MAX {
            return None;
        }
        let owner = self.owner(instance, chart);
        let (x, y) = (uv_lm.x.floor() as i64, uv_lm.y.floor() as i64);
        if let Some((t, o)) = self.entry(page, x, y) {
            if o == owner {
                return Some(t);
            }
        }
        let mut best: Option<(f32, u32)> = None;
        for dy in -1..=1 {
            for dx in -1..=1 {
                if let Some((t, o)) = self.entry(page, x + dx, y + dy) {
                    if o == owner {
                        let c = Vec2::new((x + dx) as f32 + 0.5, (y + dy) as f32 + 0.5);
                        let d = c.distance_squared(uv_lm);
                        if best.is_none_or(|(bd, _)| d < bd) {
                            best = Some((d, t));
                        }
                    }
                }
            }
        }
        best.map(|(_, t)| t)
    }

    /// [`Texels::lookup`] of every query (page, lightmap point, instance,
    /// chart), in order, with the same answers. The entries' addresses are
    /// all worked out before any is loaded, so the loads (a cache miss each
    /// on a level: the index is megabytes, and hits land anywhere) overlap
    /// instead of waiting one after the other; the rare query whose cell is
    /// not its surface's looks around as `lookup` does.
    pub fn lookup_batch(&self, queries: &[(u32, Vec2, u32, u32)], out: &mut [Option<u32>]) {
        const NOWHERE: u32 = u32::MAX;
        for (q, o) in queries
            .chunks(LOOKUP_BATCH)
            .zip(out.chunks_mut(LOOKUP_BATCH))
        {
            // (page, entry in the page) of each query's cell.
            let mut slot = [(0u32, NOWHERE); LOOKUP_BATCH];
            for (s, &(page, uv, _, chart)) in slot.iter_mut().zip(q) {
                let (x, y) = (uv.x.floor() as i64, uv.y.floor() as i64);
                let inside = x >= 0 && y >= 0 && x < self.width as i64 && y < self.height as i64;
                if chart != u32::MAX && inside {
                    *s = (page, y as u32 * self.width + x as u32);
                }
            }
            let mut entry = [EMPTY_ENTRY; LOOKUP_BATCH];
            for (e, &(page, at)) in entry.iter_mut().zip(&slot) {
                if at != NOWHERE {
                    *e = self.index[page as usize][at as usize];
                }
            }
            for ((o, &(page, uv, instance, chart)), &e) in o.iter_mut().zip(q).zip(&entry) {
                let found = e != EMPTY_ENTRY && (e >> 32) as u32 == self.owner(instance, chart);
                *o = if chart != u32::MAX && found {
                    Some(e as u32)
                } else {
                    self.lookup(page, uv, instance, chart)
                };
            }
        }
    }
}

/// Queries [`Texels::lookup_batch`] works out before loading their entries.
const LOOKUP_BATCH: usize = 16;

/// Area and centroid of triangle `t` clipped to the unit square at `(x, y)`.
///
/// Computed in the texel's own frame (corner at the origin): the shoelace
/// sums products of coordinates, and at atlas coordinates in the thousands
/// an f32 product carries an absolute error near 0.1 texel², as large as
/// the area being measured. Texels far from the atlas origin used to get
/// garbage areas and centroids (a Sponza drape's texel placed 150 m away,
/// lit by the sun there), which moved with the chart packing.
fn clip_to_texel(t: &[Vec2; 3], x: f32, y: f32) -> Option<(f32, Vec2)> {
    let origin = Vec2::new(x, y);
    let mut poly: Vec<Vec2> = t.iter().map(|&p| p - origin).collect();
    let mut next: Vec<Vec2> = Vec::with_capacity(8);
    // Four half-planes: x ≥ 0, x ≤ 1, y ≥ 0, y ≤ 1 (texel frame).
    let planes: [(usize, f32, f32); 4] =
        [(0, 0.0, 1.0), (0, 1.0, -1.0), (1, 0.0, 1.0), (1, 1.0, -1.0)];
    for (axis, bound, sign) in planes {
        next.clear();
        let inside = |p: Vec2| (p[axis] - bound) * sign >= 0.0;
        for i in 0..poly.len() {
            let a = poly[i];
            let b = poly[(i + 1) % poly.len()];
            let (ia, ib) = (inside(a), inside(b));
            if ia {
                next.push(a);
            }
            if ia != ib {
                let s = (bound - a[axis]) / (b[axis] - a[axis]);
                next.push(a + (b - a) * s);
            }
        }
        std::mem::swap(&mut poly, &mut next);
        if poly.len() < 3 {
            return None;
        }
    }
    // Shoelace area and centroid.
    let (mut a2, mut c) = (0.0f32, Vec2::ZERO);
    for i in 0..poly.len() {
        let p = poly[i];
        let q = poly[(i + 1) % poly.len()];
        let cr = p.perp_dot(q);
        a2 += cr;
        c += (p + q) * cr;
    }
    if a2.abs() <= 1e-12 {
        return None;
    }
    Some((0.5 * a2.abs(), origin + c / (3.0 * a2)))
}

/// Barycentric weights (w0, w1, w2) of `p` in triangle `t` (2D).
pub fn barycentric(t: &[Vec2; 3], p: Vec2) -> Vec3 {
    let d = (t[1] - t[0]).perp_dot(t[2] - t[0]);
    let w1 = (p - t[0]).perp_dot(t[2] - t[0]) / d;
    let w2 = (t[1] - t[0]).perp_dot(p - t[0]) / d;
    Vec3::new(1.0 - w1 - w2, w1, w2)
}

/// Supersampling grid per texel side for textured materials.
const FOOTPRINT_GRID: u32 = 4;

/// Stream purpose id of the footprint samples.
const FOOTPRINT_PURPOSE: u64 = crate::util::sampling::purpose::FOOTPRINT;

/// Mean albedo and emission of a textured `material` over the part of texel
/// `xy` that triangle `t` (lightmap corners `lm`) covers: a box filter
/// over the texel's footprint, from 4 × 4 jittered stratified points in the texel
/// that fall inside the triangle and are not cut out, each read from the
/// mipmap level as coarse as the points are apart (`mips`). The final gather
/// reads a hit's outgoing radiance as texel albedo × texel irradiance, so
/// this is the mean of ρ over the texel, not a point sample of a texture
/// that can vary much faster than the texels do (a 25 cm texel spans
/// dozens of texture pixels). `None` for untextured materials (the point
/// value is exact) and when no grid point lands in the piece.
fn footprint_mean(
    scene: &Scene,
    mips: &crate::scene::Mips,
    material: u32,
    geometry: &Geometry,
    t: u32,
    lm: &[Vec2; 3],
    xy: [i64; 2],
) -> Option<(Vec3, Vec3)> {
    let m = &scene.materials[material as usize];
    if m.albedo_texture.is_none() && m.emission_texture.is_none() {
        return None;
    }
    let (mut albedo, mut emission, mut count) = (Vec3::ZERO, Vec3::ZERO, 0u32);
    let step = 1.0 / FOOTPRINT_GRID as f32;
    // Each sample reads the mipmap level whose texels are as wide as the
    // samples are apart, so the samples together box-filter the whole
    // footprint (and read a small, cached level); a masked material's alpha
    // is tested on the texture itself, as the ray caster tests it.
    let spacing = sample_spacing(scene, geometry, t, lm, step);
    // (Under one texel apart, log2 is negative and the cast gives level 0.)
    let level = |r: &Option<crate::scene::TextureRef>| {
        r.as_ref().map_or(0, |r| spacing(r).log2().floor() as u32)
    };
    let masked = matches!(m.alpha, crate::scene::Alpha::Mask { .. });
    let albedo_level = if masked { 0 } else { level(&m.albedo_texture) };
    let emission_level = level(&m.emission_texture);
    // Jittered, not regular: a regular grid aliases with regular textures
    // (a fine checker can put every grid point on one colour).
    let item = ((t as u64) << 32) ^ ((xy[1] as u64 & 0xffff) << 16) ^ (xy[0] as u64 & 0xffff);
    let mut rng = crate::util::sampling::Stream::new(0, FOOTPRINT_PURPOSE, item);
    for j in 0..FOOTPRINT_GRID {
        for i in 0..FOOTPRINT_GRID {
            let r = rng.next_vec2();
            let p = Vec2::new(
                xy[0] as f32 + (i as f32 + r.x) * step,
                xy[1] as f32 + (j as f32 + r.y) * step,
            );
            let w = barycentric(lm, p);
            if w.min_element() < 0.0 {
                continue;
            }
            let uv0 = geometry.uv0_at(t, w.y, w.z);
            let (rho, alpha) = scene.albedo_level(material, uv0, mips, albedo_level);
            if let crate::scene::Alpha::Mask { cutoff } = m.alpha {
                if alpha < cutoff {
                    continue;
                }
            }
            albedo += rho;
            emission += scene.emission_level(material, uv0, mips, emission_level);
            count += 1;
        }
    }
    (count > 0).then(|| (albedo / count as f32, emission / count as f32))
}

/// How many texels of a texture apart footprint samples `step` lightmap
/// texels apart land on triangle `t` (at least; the fewer of the two
/// lightmap axes), per texture reference.
fn sample_spacing<'a>(
    scene: &'a Scene,
    geometry: &Geometry,
    t: u32,
    lm: &[Vec2; 3],
    step: f32,
) -> impl Fn(&crate::scene::TextureRef) -> f32 + 'a {
    // d uv0 / d lm along the lightmap's x and y, from the triangle's two
    // edges in both spaces (uv0 is affine in lm over the triangle).
    let uv = &geometry.uv0[t as usize];
    let (l1, l2) = (lm[1] - lm[0], lm[2] - lm[0]);
    let (u1, u2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let det = l1.perp_dot(l2);
    let (dx, dy) = if det.abs() > 1e-12 {
        ((u1 * l2.y - u2 * l1.y) / det, (u2 * l1.x - u1 * l2.x) / det)
    } else {
        (Vec2::ZERO, Vec2::ZERO)
    };
    move |r| {
        let tex = &scene.textures[r.texture as usize];
        // The transform's rotation keeps lengths; a texel is at most
        // 1 / min(width, height) across in uv, so this never overstates.
        let px = tex.width.min(tex.height) as f32;
        let apart = (dx * r.scale).length().min((dy * r.scale).length()) * step * px;
        if apart.is_finite() {
            apart
        } else {
            0.0
        }
    }
}

#[derive(Clone, Copy, Default)]
struct Accum {
    area: f32,
    best_cov: f32,
    tri: u32,
    chart: u32,
    p: Vec3,
    n: Vec3,
    albedo: Vec3,
    emission: Vec3,
}

/// Rows of an instance's rectangle that one task covers: a big instance
/// is split into bands of rows, so that both cores share it (Sponza's
/// largest instance held half the stage). Every band meets the triangles in
/// the same order, so each cell's sums add up exactly as in one pass.
const BAND_ROWS: u32 = 32;

/// Rasterises every triangle of `geometry` into the atlas: each instance's
/// rectangle, band by band of [`BAND_ROWS`] rows (in parallel), then the
/// covered cells numbered into texels in instance order.
pub fn rasterize(scene: &Scene, atlas: &Atlas, geometry: &Geometry) -> Texels {
    rasterize_in_bands(scene, atlas, geometry, BAND_ROWS)
}

/// [`rasterize`] with bands of `band_rows` rows.
fn rasterize_in_bands(scene: &Scene, atlas: &Atlas, geometry: &Geometry, band_rows: u32) -> Texels {
    let ranges = instance_ranges(scene, geometry);
    // Mipmaps for the footprint means, dropped when the stage ends.
    let mips = crate::scene::Mips::new(scene.textures.len());
    let bands: Vec<(usize, u32, u32)> = (0..ranges.len())
        .flat_map(|inst| instance_bands(atlas, inst, band_rows))
        .collect();
    let per_band: Vec<Band> = bands
        .par_iter()
        .map(|&(inst, y0, y1)| {
            let range = ranges[inst];
            let mut grid = InstanceGrid::new(atlas, inst, y0, y1);
            for t in range.0..range.1 {
                grid.cover(scene, &mips, geometry, t);
            }
            grid.into_band(inst)
        })
        .collect();
    let unmapped = unmapped_triangles(geometry.len(), &per_band);
    Texels {
        unmapped_triangles: unmapped,
        ..assemble(scene, atlas, geometry, per_band)
    }
}

/// The row bands `(instance, y0, y1)` of instance `inst`'s rectangle; one
/// empty band where it has no rows, so that its triangles are still counted.
fn instance_bands(atlas: &Atlas, inst: usize, rows: u32) -> Vec<(usize, u32, u32)> {
    let (_, y0, _, y1) = instance_rect(atlas, inst);
    if y1 <= y0 {
        return vec![(inst, y0, y0)];
    }
    (y0..y1)
        .step_by(rows.max(1) as usize)
        .map(|b| (inst, b, b.saturating_add(rows.max(1)).min(y1)))
        .collect()
}

/// One band's covered cells in row order, their pieces (each cell's in
/// triangle order, one flat list) and its chart overlaps.
struct Band {
    inst: usize,
    cells: Vec<Cell>,
    pieces: Vec<Piece>,
    overlaps: u64,
}

/// Triangles (of `triangles`) that left no piece in any band: unmapped,
/// degenerate in the lightmap, or wholly cut out.
fn unmapped_triangles(triangles: usize, bands: &[Band]) -> u64 {
    let mut touched = vec![false; triangles];
    for p in bands.iter().flat_map(|b| &b.pieces) {
        touched[p.tri as usize] = true;
    }
    touched.iter().filter(|&&c| !c).count() as u64
}

/// Each instance's triangles `start..end` (they are contiguous in
/// `geometry`).
fn instance_ranges(scene: &Scene, geometry: &Geometry) -> Vec<(usize, usize)> {
    let mut ranges = vec![(0usize, 0usize); scene.instances.len()];
    for (t, &i) in geometry.instance.iter().enumerate() {
        let r = &mut ranges[i as usize];
        if r.1 == 0 {
            r.0 = t;
        }
        r.1 = t + 1;
    }
    ranges
}

/// A covered cell: (x, y, sums, its pieces' range in its band's list).
type Cell = (u32, u32, Accum, std::ops::Range<usize>);

/// The cells of one band of rows of an instance's atlas rectangle, as its
/// triangles cover them.
struct InstanceGrid {
    /// The band in atlas texels: [x0, x1) × [y0, y1).
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    rw: u32,
    rh: u32,
    grid: Vec<Accum>,
    /// (cell index, piece), in triangle order.
    pieces: Vec<(u32, Piece)>,
    overlaps: u64,
}

/// Instance `inst`'s rectangle in atlas texels: (x0, y0, x1, y1).
fn instance_rect(atlas: &Atlas, inst: usize) -> (u32, u32, u32, u32) {
    let (w, h) = (atlas.width, atlas.height);
    let rect = atlas.instances[inst];
    let x0 = (rect.min[0] * w as f32).floor().max(0.0) as u32;
    let y0 = (rect.min[1] * h as f32).floor().max(0.0) as u32;
    let x1 = ((rect.max[0] * w as f32).ceil() as u32).min(w);
    let y1 = ((rect.max[1] * h as f32).ceil() as u32).min(h);
    (x0, y0, x1, y1)
}

impl InstanceGrid {
    /// Rows `y0..y1` of instance `inst`'s rectangle.
    fn new(atlas: &Atlas, inst: usize, y0: u32, y1: u32) -> Self {
        let (x0, _, x1, _) = instance_rect(atlas, inst);
        let (rw, rh) = (x1.saturating_sub(x0), y1.saturating_sub(y0));
        InstanceGrid {
            x0,
            y0,
            x1,
            y1,
            rw,
            rh,
            grid: vec![Accum::default(); (rw * rh) as usize],
            pieces: Vec::new(),
            overlaps: 0,
        }
    }

    /// Adds triangle `t`'s exact coverage of every texel of the band it
    /// touches: the clipped area, centroid, normal, footprint-mean albedo
    /// and emission, and one piece per texel. Cut-out (alpha-masked) parts
    /// cover nothing.
    fn cover(&mut self, scene: &Scene, mips: &crate::scene::Mips, geometry: &Geometry, t: usize) {
        let lm = geometry.uv_lm[t];
        let lm_area = 0.5 * (lm[1] - lm[0]).perp_dot(lm[2] - lm[0]).abs();
        if lm_area <= 1e-10 || geometry.chart[t] == u32::MAX {
            return;
        }
        let world_per_texel = geometry.area[t] / lm_area;
        let lo = lm[0].min(lm[1]).min(lm[2]).floor();
        let hi = lm[0].max(lm[1]).max(lm[2]).ceil();
        let tx0 = (lo.x as i64).max(self.x0 as i64);
        let ty0 = (lo.y as i64).max(self.y0 as i64);
        let tx1 = (hi.x as i64).min(self.x1 as i64);
        let ty1 = (hi.y as i64).min(self.y1 as i64);
        for y in ty0..ty1 {
            for x in tx0..tx1 {
                let Some((cov, centroid)) = clip_to_texel(&lm, x as f32, y as f32) else {
                    continue;
                };
                let bary = barycentric(&lm, centroid);
                let (u, v) = (bary.y, bary.z);
                let material = geometry.material[t];
                let uv0 = geometry.uv0_at(t as u32, u, v);
                if scene.is_cut_out(material, uv0) {
                    continue;
                }
                let a = cov * world_per_texel;
                let index = (y as u32 - self.y0) * self.rw + (x as u32 - self.x0);
                self.pieces.push((
                    index,
                    Piece {
                        tri: t as u32,
                        u,
                        v,
                        area: a,
                    },
                ));
                let cell = &mut self.grid[index as usize];
                if cell.area > 0.0 && cell.chart != geometry.chart[t] {
                    self.overlaps += 1;
                }
                if cov > cell.best_cov {
                    cell.best_cov = cov;
                    cell.tri = t as u32;
                    cell.chart = geometry.chart[t];
                }
                cell.area += a;
                cell.p += geometry.point(t as u32, u, v) * a;
                cell.n += geometry.ng_ws[t] * a;
                let (albedo, emission) =
                    footprint_mean(scene, mips, material, geometry, t as u32, &lm, [x, y])
                        .unwrap_or_else(|| {
                            (
                                scene.albedo_at(material, uv0).0,
                                scene.emission_at(material, uv0),
                            )
                        });
                cell.albedo += albedo * a;
                cell.emission += emission * a;
            }
        }
    }

    /// The band: its covered cells in row order, each with its pieces (in
    /// triangle order within a cell).
    fn into_band(mut self, inst: usize) -> Band {
        // Stable: a cell's pieces stay in triangle order.
        self.pieces.sort_by_key(|p| p.0);
        let mut cells = Vec::new();
        let mut at = 0;
        for y in 0..self.rh {
            for x in 0..self.rw {
                let index = y * self.rw + x;
                let start = at;
                while at < self.pieces.len() && self.pieces[at].0 == index {
                    at += 1;
                }
                let c = self.grid[index as usize];
                if c.area > 0.0 {
                    cells.push((self.x0 + x, self.y0 + y, c, start..at));
                }
            }
        }
        Band {
            inst,
            cells,
            pieces: self.pieces.into_iter().map(|p| p.1).collect(),
            overlaps: self.overlaps,
        }
    }
}

/// Owner ids: each instance's charts numbered after the previous
/// instance's (its mesh's highest chart + 1).
fn owner_bases(scene: &Scene, atlas: &Atlas) -> Vec<u32> {
    let charts_of_mesh: Vec<u64> = atlas
        .meshes
        .iter()
        .map(|m| {
            m.chart
                .iter()
                .filter(|&&c| c != u32::MAX)
                .max()
                .map_or(0, |&c| c as u64 + 1)
        })
        .collect();
    let mut owner_base = Vec::with_capacity(scene.instances.len());
    let mut next_owner = 0u64;
    for inst in &scene.instances {
        owner_base.push(next_owner.min(u32::MAX as u64) as u32);
        next_owner += charts_of_mesh.get(inst.mesh as usize).copied().unwrap_or(0);
    }
    owner_base
}

/// The texels, numbered in instance order (the bands in order), and the
/// page index.
fn assemble(scene: &Scene, atlas: &Atlas, geometry: &Geometry, bands: Vec<Band>) -> Texels {
    let (w, h) = (atlas.width, atlas.height);
    let mut tx = Texels {
        index: vec![vec![EMPTY_ENTRY; (w * h) as usize]; atlas.page_count.max(1) as usize],
        owner_base: owner_bases(scene, atlas),
        width: w,
        height: h,
        ..Default::default()
    };
    for band in bands {
        let inst = band.inst;
        tx.chart_overlaps += band.overlaps;
        let page = atlas.instances[inst].page;
        for (x, y, c, pieces) in band.cells {
            let id = tx.len() as u32;
            let slot = &mut tx.index[page as usize][(y * w + x) as usize];
            if *slot != EMPTY_ENTRY {
                // Two instances claim one texel: keep the first (never
                // happens with a valid atlas).
                tx.chart_overlaps += 1;
                continue;
            }
            let owner = tx.owner_base[inst].wrapping_add(c.chart) as u64;
            *slot = (owner << 32) | id as u64;
            tx.page.push(page);
            tx.xy.push([x, y]);
            tx.instance.push(inst as u32);
            tx.chart.push(c.chart);
            tx.triangle.push(c.tri);
            tx.p_ws.push(c.p / c.area);
            tx.n_ws
                .push(c.n.normalize_or(geometry.ng_ws[c.tri as usize]));
            tx.area.push(c.area);
            if tx.piece_start.is_empty() {
                tx.piece_start.push(0);
            }
            tx.pieces.extend_from_slice(&band.pieces[pieces]);
            tx.piece_start.push(tx.pieces.len() as u32);
            tx.albedo.push(c.albedo / c.area);
            tx.emission.push(c.emission / c.area);
        }
    }
    tx
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two unit quads at an angle (two charts), one mesh, two instances,
    /// and one degenerate triangle per instance.
    fn bent_scene() -> Scene {
        use crate::scene::{Instance, Material, Mesh};
        use glam::{Mat4, Vec3};
        let mut m = Mesh {
            name: "bent".into(),
            ..Default::default()
        };
        for (k, n) in [Vec3::Y, Vec3::X].into_iter().enumerate() {
            let base = m.positions.len() as u32;
            let c = Vec3::new(k as f32 * 3.0, 0.0, 0.0);
            let (t, b) = crate::util::sampling::frame(n);
            for (u, v) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                m.positions.push(c + t * u + b * v);
                m.normals.push(n);
                m.uv0.push(Vec2::ZERO);
            }
            m.triangles.push([base, base + 1, base + 2]);
            m.triangles.push([base, base + 2, base + 3]);
            m.triangle_material.extend([0, 0]);
        }
        m.triangles.push([0, 1, 1]);
        m.triangle_material.push(0);
        Scene {
            meshes: vec![m],
            instances: (0..2)
                .map(|i| Instance {
                    node: format!("n{i}"),
                    texel_scale: 1.0,
                    cast_shadows: true,
                    lightmap: true,
                    node_index: i,
                    mesh: 0,
                    world_from_local: Mat4::from_translation(Vec3::Z * 5.0 * i as f32),
                })
                .collect(),
            materials: vec![Material::fallback()],
            ..Default::default()
        }
    }

    /// [`bent_scene`] unwrapped at `texels_per_meter`, with its geometry.
    fn bent_atlas(texels_per_meter: f32) -> (Scene, Atlas, Geometry) {
        let scene = bent_scene();
        let config = crate::BakeConfig {
            texels_per_meter,
            ..Default::default()
        };
        let atlas = crate::layout::atlas::unwrap(&scene, &config).unwrap();
        let geometry = Geometry::new(&scene, &atlas);
        (scene, atlas, geometry)
    }

    /// A texel's packed index entry names it and its owner (instance, chart):
    /// every texel of two instances of one mesh is found at its own lightmap
    /// point for its own owner and for no other, and owners are distinct.
    #[test]
    fn lookup_finds_texels_by_owner() {
        let (scene, atlas, geometry) = bent_atlas(8.0);
        let tx = rasterize(&scene, &atlas, &geometry);
        assert!(tx.len() > 100, "{} texels", tx.len());
        let mut owners = std::collections::BTreeSet::new();
        for t in 0..tx.len() {
            let (inst, chart) = (tx.instance[t], tx.chart[t]);
            owners.insert((tx.owner(inst, chart), inst, chart));
            let [x, y] = tx.xy[t];
            let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            assert_eq!(tx.lookup(tx.page[t], p, inst, chart), Some(t as u32));
            assert_eq!(tx.lookup(tx.page[t], p, 1 - inst, chart), None);
            assert_eq!(tx.lookup(tx.page[t], p, inst, u32::MAX), None);
        }
        let distinct: std::collections::BTreeSet<u32> = owners.iter().map(|o| o.0).collect();
        assert_eq!(distinct.len(), owners.len(), "owners collide: {owners:?}");
        assert!(owners.len() >= 4, "two charts per instance: {owners:?}");
    }

    /// Bands of any height give the texels of one pass over the whole
    /// rectangle, bit for bit, and count each unmapped triangle once.
    #[test]
    fn bands_change_no_texel() {
        let (scene, atlas, geometry) = bent_atlas(40.0);
        let key = |t: &Texels| {
            format!(
                "{:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {}",
                t.xy,
                t.area,
                t.p_ws,
                t.n_ws,
                t.albedo,
                t.triangle,
                t.pieces,
                t.piece_start,
                t.index,
                t.chart_overlaps
            )
        };
        let whole = rasterize_in_bands(&scene, &atlas, &geometry, u32::MAX);
        assert!(whole.len() > 1000, "{} texels", whole.len());
        assert_eq!(whole.unmapped_triangles, 2);
        for rows in [1, 3, 32] {
            let banded = rasterize_in_bands(&scene, &atlas, &geometry, rows);
            assert_eq!(banded.unmapped_triangles, 2, "bands of {rows}");
            assert!(key(&banded) == key(&whole), "bands of {rows} rows differ");
        }
    }

    #[test]
    fn clip_full_and_partial() {
        let big = [
            Vec2::new(-10.0, -10.0),
            Vec2::new(10.0, -10.0),
            Vec2::new(0.0, 10.0),
        ];
        let (a, c) = clip_to_texel(&big, 0.0, 0.0).unwrap();
        assert!((a - 1.0).abs() < 1e-5 && (c - Vec2::splat(0.5)).length() < 1e-5);
        // Lower-left half of the texel.
        let half = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
        ];
        let (a, c) = clip_to_texel(&half, 0.0, 0.0).unwrap();
        assert!((a - 0.5).abs() < 1e-6 && (c - Vec2::splat(1.0 / 3.0)).length() < 1e-5);
        assert!(clip_to_texel(&half, 3.0, 3.0).is_none());
    }

    /// Far from the atlas origin the clip is as exact as near it (regression:
    /// the shoelace on absolute coordinates lost the area to f32 rounding).
    /// Triangles of a Sponza drape near texel (1137, 1509) of a 1260 × 1704
    /// atlas, against the same triangles moved (exactly) to texel (0, 0).
    #[test]
    fn clip_far_from_the_origin() {
        let far = [
            [
                (1137.2583, 1508.9515),
                (1137.2177, 1509.364),
                (1136.9434, 1509.2998),
            ],
            [
                (1137.0109, 1508.8938),
                (1136.6068, 1509.2177),
                (1136.7118, 1508.8007),
            ],
            [
                (1136.9434, 1509.2998),
                (1136.6056, 1509.6346),
                (1136.6068, 1509.2177),
            ],
        ];
        for tri in far {
            let t = tri.map(|(a, b)| Vec2::new(a, b));
            let mid = (t[0] + t[1] + t[2]) / 3.0;
            let (x, y) = (mid.x.floor(), mid.y.floor());
            let local = t.map(|p| p - Vec2::new(x, y));
            let (a_far, c_far) = clip_to_texel(&t, x, y).unwrap();
            let (a_near, c_near) = clip_to_texel(&local, 0.0, 0.0).unwrap();
            assert!(
                (a_far - a_near).abs() <= 1e-6 * a_near.max(1.0),
                "{a_far} vs {a_near}"
            );
            assert!(
                (c_far - Vec2::new(x, y) - c_near).length() < 1e-4,
                "{c_far} vs {c_near}"
            );
            // The centroid lies inside its triangle.
            let w = barycentric(&t, c_far);
            assert!(w.min_element() > -1e-3, "{w}");
        }
    }

    /// Exact coverage conserves area: a thin sliver still covers its texels
    /// and their clipped areas add up to its own.
    #[test]
    fn coverage_sums_to_triangle_area() {
        let t = [
            Vec2::new(0.3, 0.2),
            Vec2::new(7.9, 0.35),
            Vec2::new(4.1, 0.5),
        ];
        let area = 0.5 * (t[1] - t[0]).perp_dot(t[2] - t[0]).abs();
        let mut sum = 0.0;
        for y in 0..2 {
            for x in 0..9 {
                if let Some((a, _)) = clip_to_texel(&t, x as f32, y as f32) {
                    sum += a;
                }
            }
        }
        assert!((sum - area).abs() < 1e-5 * area.max(1.0), "{sum} vs {area}");
    }

    #[test]
    fn barycentric_of_vertices() {
        let t = [
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(0.0, 3.0),
        ];
        assert!((barycentric(&t, t[1]) - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6);
        assert!((barycentric(&t, t[2]) - Vec3::new(0.0, 0.0, 1.0)).length() < 1e-6);
    }
}
