//! Form factors by the hemicube (Cohen & Greenberg 1985), on the CPU.
//!
//! A half cube of unit height is set on patch i's centroid along its normal:
//! a full top face (N × N pixels over [−1, 1]²) and four half side faces
//! (N × N/2). Every scene triangle is projected onto each face with a
//! z-buffer (near-plane clipping; triangles outside the face's frustum are
//! culled by their bounding sphere); each pixel then holds the closest
//! surface, which is resolved to its lightmap texel and so to its patch.
//! Each pixel carries its precomputed delta form factor
//!
//! top:  ΔF = ΔA / (π (x² + y² + 1)²)       side: ΔF = z ΔA / (π (x² + z² + 1)²)
//!
//! with ΔA = (2/N)², which together sum to 1 (0.554 top + 4 × 0.111 sides),
//! and Fᵢⱼ = Σ ΔF over pixels that show patch j.

use super::{FormFactorStats, FormFactors};
use crate::layout::texels::EMPTY_ENTRY;
use crate::surface::{Landing, Surfaces};
use crate::util::sampling::{frame, offset_ray_origin};
use glam::{Vec2, Vec3};
use wide::{f32x4, CmpGe, CmpGt, CmpLt};

/// Delta form factors of one hemicube resolution.
#[derive(Clone, Debug)]
pub struct Hemicube {
    /// Top-face resolution N (even).
    pub n: u32,
    /// N × N top-face delta form factors, row-major (row = y).
    pub top: Vec<f32>,
    /// N × N/2 side-face delta form factors, row 0 at the surface plane.
    pub side: Vec<f32>,
}

impl Hemicube {
    /// Precomputes the delta form factors for resolution `n` (rounded up to even).
    pub fn new(n: u32) -> Hemicube {
        let n = (n.max(2) + 1) & !1;
        let d = 2.0 / n as f64;
        let da = d * d;
        let pi = std::f64::consts::PI;
        let mut top = Vec::with_capacity((n * n) as usize);
        for y in 0..n {
            for x in 0..n {
                let px = -1.0 + (x as f64 + 0.5) * d;
                let py = -1.0 + (y as f64 + 0.5) * d;
                top.push((da / (pi * (px * px + py * py + 1.0).powi(2))) as f32);
            }
        }
        let mut side = Vec::with_capacity((n * n / 2) as usize);
        for z in 0..n / 2 {
            for x in 0..n {
                let px = -1.0 + (x as f64 + 0.5) * d;
                let pz = (z as f64 + 0.5) * d;
                side.push((pz * da / (pi * (px * px + pz * pz + 1.0).powi(2))) as f32);
            }
        }
        Hemicube { n, top, side }
    }
}

/// A face's camera: right, up, forward, and the rows it covers.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Face {
    pub(crate) right: Vec3,
    pub(crate) up: Vec3,
    pub(crate) forward: Vec3,
    /// Side faces cover only up ∈ [0, 1] (rows `0..n/2` of the up axis).
    pub(crate) side: bool,
}

/// A rasterised pixel: closest depth, its triangle and the barycentric
/// weights of the triangle's corners 1 and 2 at the pixel's centre
/// (perspective-correct), so the pixel lands on its texel without a ray.
#[derive(Clone, Copy)]
pub(crate) struct Pixel {
    pub(crate) depth: f32,
    pub(crate) tri: u32,
    pub(crate) u: f32,
    pub(crate) v: f32,
}

pub(crate) const EMPTY: Pixel = Pixel {
    depth: f32::INFINITY,
    tri: u32::MAX,
    u: 0.0,
    v: 0.0,
};

/// A clipped polygon's corner: camera-space position and the barycentric
/// weights (corners 1, 2) of the original triangle there.
#[derive(Clone, Copy, Default)]
struct Corner {
    cam: Vec3,
    bary: Vec2,
}

/// Most corners a triangle clipped by five planes can have.
const MAX_CORNERS: usize = 8;

/// Rasterises every triangle of the scene onto one face of the hemicube at
/// `eye`; `buf` is `n × rows`, rows along `up` from `up_min`.
fn rasterize_face(s: &Surfaces, eye: Vec3, face: &Face, n: u32, buf: &mut [Pixel]) {
    let rows = if face.side { n / 2 } else { n };
    let up_min = if face.side { 0.0 } else { -1.0 };
    let near = 1e-5f32;
    let g = s.geometry;
    let to_screen = |c: Vec3| -> Vec3 {
        // Camera space (x right, y up, z forward) → pixel coords + depth.
        Vec3::new(
            (c.x / c.z + 1.0) * 0.5 * n as f32,
            (c.y / c.z - up_min) * 0.5 * n as f32,
            c.z,
        )
    };
    for (t, p) in g.p_ws.iter().enumerate() {
        // Camera-space corners.
        let cam = p.map(|v| {
            let d = v - eye;
            Vec3::new(d.dot(face.right), d.dot(face.up), d.dot(face.forward))
        });
        // Cull: entirely behind the near plane or outside a side of the frustum.
        if cam.iter().all(|c| c.z <= near)
            || cam.iter().all(|c| c.x > c.z)
            || cam.iter().all(|c| c.x < -c.z)
            || cam.iter().all(|c| c.y > c.z)
            || cam.iter().all(|c| c.y < up_min * c.z)
        {
            continue;
        }
        // Clip against the whole frustum (near plane and the four sides,
        // widened by 0.1 % so shared edges are covered), so projected
        // coordinates stay bounded and the f32 edge functions exact enough.
        // The corners carry their barycentric weights (linear in camera
        // space, as the clip's interpolation is).
        let e = 1.001;
        let planes = [
            glam::Vec4::new(0.0, 0.0, 1.0, -near),
            glam::Vec4::new(-1.0, 0.0, e, 0.0),
            glam::Vec4::new(1.0, 0.0, e, 0.0),
            glam::Vec4::new(0.0, -1.0, e, 0.0),
            if face.side {
                glam::Vec4::new(0.0, 1.0, 0.001, 0.0)
            } else {
                glam::Vec4::new(0.0, 1.0, e, 0.0)
            },
        ];
        let mut poly = [Corner::default(); MAX_CORNERS + 1];
        let mut next = [Corner::default(); MAX_CORNERS + 1];
        let bary = [Vec2::ZERO, Vec2::X, Vec2::Y];
        for k in 0..3 {
            poly[k] = Corner {
                cam: cam[k],
                bary: bary[k],
            };
        }
        let mut len = 3;
        for pl in planes {
            let d = |c: Vec3| pl.truncate().dot(c) + pl.w;
            let mut m = 0;
            for k in 0..len {
                let (a, b) = (poly[k], poly[(k + 1) % len]);
                let (da, db) = (d(a.cam), d(b.cam));
                if da >= 0.0 && m < MAX_CORNERS {
                    next[m] = a;
                    m += 1;
                }
                if (da >= 0.0) != (db >= 0.0) && m < MAX_CORNERS {
                    let f = da / (da - db);
                    next[m] = Corner {
                        cam: a.cam + (b.cam - a.cam) * f,
                        bary: a.bary + (b.bary - a.bary) * f,
                    };
                    m += 1;
                }
            }
            std::mem::swap(&mut poly, &mut next);
            len = m;
            if len < 3 {
                break;
            }
        }
        if len < 3 {
            continue;
        }
        let scr = poly.map(|c| (to_screen(c.cam), c.bary));
        for k in 1..len - 1 {
            raster_triangle(&[scr[0], scr[k], scr[k + 1]], t as u32, n, rows, buf);
        }
    }
}

/// Edge-function rasterisation of one screen-space triangle (x, y in pixels,
/// z = view depth; each corner with its barycentric weights) with a depth
/// test on 1/z interpolated linearly; the weights are interpolated
/// perspective-correctly (a / z linear in screen space).
fn raster_triangle(v: &[(Vec3, Vec2); 3], tri: u32, n: u32, rows: u32, buf: &mut [Pixel]) {
    let (a, b, c) = (v[0].0, v[1].0, v[2].0);
    let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if area.abs() < 1e-12 {
        return;
    }
    let [min_x, max_x, min_y, max_y] = pixel_bounds(v, n, rows);
    let inv_z = [1.0 / a.z, 1.0 / b.z, 1.0 / c.z];
    let t = ScreenTriangle {
        a,
        b,
        c,
        inv_area: 1.0 / area,
        inv_z,
        bary_z: [v[0].1 * inv_z[0], v[1].1 * inv_z[1], v[2].1 * inv_z[2]],
        tri,
    };
    for y in min_y..max_y {
        let py = y as f32 + 0.5;
        let (x0, x1) = t.row_span(py, min_x, max_x);
        let row = &mut buf[(y as u32 * n) as usize..][..n as usize];
        t.raster_row(row, py, x0, x1);
    }
}

/// The pixels a triangle's screen bounding box covers, clamped to the face:
/// `[min_x, max_x, min_y, max_y]` (max exclusive).
#[inline]
fn pixel_bounds(v: &[(Vec3, Vec2); 3], n: u32, rows: u32) -> [i64; 4] {
    let xs = [v[0].0.x, v[1].0.x, v[2].0.x];
    let ys = [v[0].0.y, v[1].0.y, v[2].0.y];
    let least = |z: [f32; 3]| {
        z.iter()
            .copied()
            .fold(f32::INFINITY, f32::min)
            .floor()
            .max(0.0)
    };
    let most = |z: [f32; 3], cap: u32| {
        (z.iter().copied())
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil()
            .min(cap as f32)
    };
    [
        least(xs) as i64,
        most(xs, n) as i64,
        least(ys) as i64,
        most(ys, rows) as i64,
    ]
}

/// One screen triangle's constants for [`raster_triangle`]: its vertices
/// (x, y in pixels, z the depth), 1 / its doubled signed area, 1/z and
/// barycentrics / z at each vertex (perspective-correct interpolation),
/// and its id.
struct ScreenTriangle {
    a: Vec3,
    b: Vec3,
    c: Vec3,
    inv_area: f32,
    inv_z: [f32; 3],
    bary_z: [Vec2; 3],
    tri: u32,
}

impl ScreenTriangle {
    /// Row `py`'s span of pixels that may be inside: each edge function is
    /// linear in x, so the pixels inside lie in one interval, found per edge
    /// and widened by a pixel; the exact test of [`ScreenTriangle::raster_row`]
    /// decides each pixel in it.
    #[inline]
    fn row_span(&self, py: f32, min_x: i64, max_x: i64) -> (i64, i64) {
        let (a, b, c) = (self.a, self.b, self.c);
        let (mut lo, mut hi) = (min_x as f32, max_x as f32);
        for (ea, eb) in [(b, c), (c, a), (a, b)] {
            let slope = -(eb.y - ea.y) * self.inv_area;
            let at0 = ((eb.x - ea.x) * (py - ea.y) + (eb.y - ea.y) * ea.x) * self.inv_area;
            if slope > 0.0 {
                lo = lo.max(-at0 / slope - 1.5);
            } else if slope < 0.0 {
                hi = hi.min(-at0 / slope + 1.5);
            } else if at0 < 0.0 {
                hi = lo;
            }
        }
        ((lo.max(min_x as f32)) as i64, (hi.min(max_x as f32)) as i64)
    }

    /// Pixels `x0..x1` of the row at `py`, depth-tested and written.
    ///
    /// Four pixels at a time: their weights, coverage and depths in the
    /// lanes of `f32x4`, each lane the one-pixel arithmetic (edge
    /// functions, then 1 − w0 − w1, then 1/z) in that order, so the same
    /// bits; lanes past the span count as outside. Then the covered ones
    /// are tested and written one by one.
    #[inline]
    fn raster_row(&self, row: &mut [Pixel], py: f32, x0: i64, x1: i64) {
        let (a, b, c) = (self.a, self.b, self.c);
        let (inv_area, inv_z, bary_z, tri) = (self.inv_area, self.inv_z, self.bary_z, self.tri);
        let (k0, k1) = ((c.x - b.x) * (py - b.y), (a.x - c.x) * (py - c.y));
        let zero = f32x4::splat(0.0);
        // Pixel centres x + 0.5 … x + 3.5: exact sums of small integers
        // and halves, so the same bits as each centre's own conversion.
        let offsets = f32x4::new([0.5, 1.5, 2.5, 3.5]);
        for x in (x0..x1).step_by(4) {
            let px = f32x4::splat(x as f32) + offsets;
            let w0 = (f32x4::splat(k0) - f32x4::splat(c.y - b.y) * (px - f32x4::splat(b.x)))
                * f32x4::splat(inv_area);
            let w1 = (f32x4::splat(k1) - f32x4::splat(a.y - c.y) * (px - f32x4::splat(c.x)))
                * f32x4::splat(inv_area);
            let w2 = f32x4::splat(1.0) - w0 - w1;
            let outside = w0.cmp_lt(zero) | w1.cmp_lt(zero) | w2.cmp_lt(zero);
            let in_span = (1 << (x1 - x).min(4)) - 1;
            let covered = !outside.move_mask() & in_span;
            if covered == 0 {
                continue;
            }
            let iz = w0 * f32x4::splat(inv_z[0])
                + w1 * f32x4::splat(inv_z[1])
                + w2 * f32x4::splat(inv_z[2]);
            let depth = f32x4::splat(1.0) / iz;
            // The perspective-correct weights, lane by lane as a `Vec2`'s
            // arithmetic would give them.
            let bz = |a: usize| {
                ((f32x4::splat(bary_z[0][a]) * w0 + f32x4::splat(bary_z[1][a]) * w1)
                    + f32x4::splat(bary_z[2][a]) * w2)
                    * depth
            };
            let (u, v) = (bz(0).to_array(), bz(1).to_array());
            let x = x as usize;
            let write = |row: &mut [Pixel], k: usize, d: f32| {
                row[x + k] = Pixel {
                    depth: d,
                    tri,
                    u: u[k],
                    v: v[k],
                }
            };
            if covered == 0b1111 {
                // Four pixels inside the row: one depth test of all four,
                // and where all pass (most groups), four writes without a
                // branch between them.
                let old = f32x4::new([0, 1, 2, 3].map(|k| row[x + k].depth));
                let pass = depth.cmp_lt(old).move_mask();
                let depth = depth.to_array();
                if pass == 0b1111 {
                    for (k, &d) in depth.iter().enumerate() {
                        write(row, k, d);
                    }
                    continue;
                }
                for k in (0..4).filter(|k| pass >> k & 1 == 1) {
                    write(row, k, depth[k]);
                }
                continue;
            }
            let depth = depth.to_array();
            for k in (0..4).filter(|k| covered >> k & 1 == 1) {
                if depth[k] < row[x + k].depth {
                    write(row, k, depth[k]);
                }
            }
        }
    }
}

/// Where patch i's hemicube stands: its eye, just off the surface, and
/// the five face cameras (top, then the four half sides).
pub(crate) struct Cameras {
    pub(crate) eye: Vec3,
    pub(crate) faces: [Face; 5],
}

/// Patch i's hemicube cameras; `None` for a buried patch (an empty row).
pub(crate) fn cameras(s: &Surfaces, i: usize) -> Option<Cameras> {
    if s.patch_buried(i) {
        return None;
    }
    let nrm = s.patches.n_ws[i];
    // Eye: the patch centroid pulled onto its nearest texel's surface, off it by an offset.
    let eye_surface = s.patches.p_ws[i];
    let eye =
        offset_ray_origin(eye_surface, nrm) + nrm * 1e-5 * (1.0 + eye_surface.abs().max_element());
    let (t, b) = frame(nrm);
    let face = |right, up, forward, side| Face {
        right,
        up,
        forward,
        side,
    };
    Some(Cameras {
        eye,
        faces: [
            face(t, b, nrm, false),
            face(-b, nrm, t, true),
            face(b, nrm, -t, true),
            face(t, nrm, b, true),
            face(-t, nrm, -b, true),
        ],
    })
}

/// Every lightmap cell's patch, for the hemicube's per-pixel landing: per
/// page cell the patch of its texel in the low 32 bits ([`SPLIT`] where
/// burial planes split the texel, so the point decides) and the texel's
/// owner ([`crate::layout::texels::Texels::owner`]) in the high ones, or
/// [`EMPTY_ENTRY`]. One load lands a pixel where the atlas's index, the
/// split bits and the texel's patch took three dependent ones: a
/// furnace hemicube's pixels each show a different cell (4.5 texels per
/// pixel at the defaults), so those loads were most of its time.
pub struct CellPatches {
    /// Every page's cells, one page after another.
    entries: Vec<u64>,
    width: u32,
    height: u32,
}

/// A cell whose texel burial planes split: [`Surfaces::land`] decides.
const SPLIT: u32 = u32::MAX;

impl CellPatches {
    /// The map of `s`'s atlas.
    pub fn new(s: &Surfaces) -> CellPatches {
        let tx = s.texels;
        let entries = (tx.index.iter().flatten())
            .map(|&e| {
                if e == EMPTY_ENTRY {
                    return e;
                }
                let texel = e as u32;
                let patch = if s.burial.split(texel as usize) {
                    SPLIT
                } else {
                    s.patches.of_texel[texel as usize].0
                };
                (e & !u64::from(u32::MAX)) | u64::from(patch)
            })
            .collect();
        CellPatches {
            entries,
            width: tx.width,
            height: tx.height,
        }
    }

    /// Where `page`'s first cell is in [`CellPatches::entries`].
    #[inline(always)]
    fn page_start(&self, page: u32) -> usize {
        page as usize * self.height as usize * self.width as usize
    }
}

/// The cell-map slots of four pixels of one triangle (barycentric
/// weights (u, v) of its corners 1 and 2), or [`LAND`] off the page: the
/// lightmap position t₀(1 − u − v) + t₁u + t₂v and its floor in the lanes
/// of `f32x4`, each lane the arithmetic of [`Geometry::uv_lm_at`] and an
/// exact floor, so the same cells as one pixel at a time. A NaN or a
/// position out of `i32`'s range fails the bounds test (it truncates to
/// `i32::MIN`).
///
/// [`Geometry::uv_lm_at`]: crate::layout::geometry::Geometry::uv_lm_at
#[inline(always)]
fn cells4(cells: &CellPatches, page: usize, t: &[Vec2; 3], uv: [(f32, f32); 4]) -> [usize; 4] {
    let u = f32x4::new(uv.map(|p| p.0));
    let v = f32x4::new(uv.map(|p| p.1));
    let w = f32x4::splat(1.0) - u - v;
    let axis = |a: usize| {
        let x = f32x4::splat(t[0][a]) * w + f32x4::splat(t[1][a]) * u + f32x4::splat(t[2][a]) * v;
        let whole = x.fast_trunc_int().round_float();
        // ⌊x⌋: the truncation, one less where it rounded up (x < 0).
        whole - (whole.cmp_gt(x) & f32x4::splat(1.0))
    };
    let (x, y) = (axis(0), axis(1));
    let (w, h) = (cells.width as f32, cells.height as f32);
    let zero = f32x4::splat(0.0);
    let inside =
        (x.cmp_ge(zero) & x.cmp_lt(f32x4::splat(w)) & y.cmp_ge(zero) & y.cmp_lt(f32x4::splat(h)))
            .move_mask();
    let (xi, yi) = (x.fast_trunc_int().to_array(), y.fast_trunc_int().to_array());
    std::array::from_fn(|k| {
        if inside >> k & 1 == 1 {
            page + yi[k] as usize * cells.width as usize + xi[k] as usize
        } else {
            LAND
        }
    })
}

/// What landing a patch's hemicube needs besides the scene: the delta
/// form factors of its resolution and the atlas's cell map.
pub struct Setup {
    /// Delta form factors.
    pub cube: Hemicube,
    /// Every cell's patch.
    pub cells: CellPatches,
}

impl Setup {
    /// Hemicubes of resolution `n` over `s`'s atlas.
    pub fn new(s: &Surfaces, n: u32) -> Setup {
        Setup {
            cube: Hemicube::new(n),
            cells: CellPatches::new(s),
        }
    }
}

/// Pixels landed together: their cells' entries are loaded in one pass
/// with no branch between the loads, so that their cache misses overlap.
const BATCH: usize = 256;

/// What the first pass found for a pixel (besides a cell to load).
const ESCAPED: usize = usize::MAX;
const BACK_FACE: usize = usize::MAX - 1;
/// Off the page or on a triangle without a chart: [`Surfaces::land`].
const LAND: usize = usize::MAX - 2;

/// Turns rasterised faces into a row: every pixel lands on the patch of
/// the lightmap texel it shows and adds its delta form factor there.
/// Shared by the CPU rasteriser and the GPU's ([`super::gpu_hemicube`]),
/// so both devices land pixels by the same code.
pub(crate) struct Resolve<'a> {
    s: &'a Surfaces<'a>,
    setup: &'a Setup,
    eye: Vec3,
    /// Σ ΔF per patch, dense, and the patches touched (in first-seen
    /// order): `touched[..count]`, with room for every patch and one more,
    /// as each pixel writes its patch there and counts it only if new.
    sums: Vec<f32>,
    touched: Vec<u32>,
    count: usize,
    stats: FormFactorStats,
}

impl<'a> Resolve<'a> {
    pub(crate) fn new(s: &'a Surfaces<'a>, setup: &'a Setup, eye: Vec3) -> Self {
        Resolve {
            s,
            setup,
            eye,
            sums: vec![0.0; s.patches.len()],
            touched: vec![0; s.patches.len() + 1],
            count: 0,
            stats: FormFactorStats::default(),
        }
    }

    /// Adds one face's pixels (`n` × rows, rows along `up` from its lower
    /// edge), [`BATCH`] at a time: each pixel's cell (or what it is
    /// instead), then the cells' entries, then the sums, in pixel order.
    pub(crate) fn face(&mut self, face: &Face, pixels: &[Pixel]) {
        let cube = &self.setup.cube;
        let weights = if face.side { &cube.side } else { &cube.top };
        self.stats.rays += pixels.len() as u64;
        let mut slots = [0usize; BATCH + 3];
        let mut owners = [0u32; BATCH];
        let mut entries = [0u64; BATCH + 3];
        for (b, chunk) in pixels.chunks(BATCH).enumerate() {
            self.cells_of(chunk, &mut slots, &mut owners, &mut entries);
            let weights = &weights[b * BATCH..b * BATCH + chunk.len()];
            self.add(face, chunk, &slots, &owners, &entries, weights);
        }
    }

    /// Each pixel's slot in the cell map and its triangle's owner, or
    /// [`ESCAPED`], [`BACK_FACE`] or [`LAND`]. Runs of pixels show one
    /// triangle: its side, page and owner are found once per run, and its
    /// pixels' cells four at a time ([`cells4`]).
    #[inline(always)]
    fn cells_of(
        &self,
        chunk: &[Pixel],
        slots: &mut [usize; BATCH + 3],
        owners: &mut [u32; BATCH],
        entries: &mut [u64; BATCH + 3],
    ) {
        let (s, eye) = (self.s, self.eye);
        let g = s.geometry;
        let cells = &self.setup.cells;
        let mut k = 0;
        while k < chunk.len() {
            let tri = chunk[k].tri;
            let end = k + chunk[k..].iter().take_while(|p| p.tri == tri).count();
            let run = k..end;
            k = end;
            if tri == u32::MAX {
                slots[run].fill(ESCAPED);
                continue;
            }
            let t = tri as usize;
            if !s.seen_from(tri, eye) {
                slots[run].fill(BACK_FACE);
                continue;
            }
            let owner = if g.chart[t] == u32::MAX {
                u32::MAX
            } else {
                s.texels.owner(g.instance[t], g.chart[t])
            };
            if owner == u32::MAX {
                entries[run.clone()].fill(EMPTY_ENTRY);
                slots[run].fill(LAND);
                continue;
            }
            owners[run.clone()].fill(owner);
            let page = cells.page_start(g.page[t]);
            let uv = &g.uv_lm[t];
            let mut p = run.start;
            while p < run.end {
                let m = (run.end - p).min(4);
                let lanes: [usize; 4] = std::array::from_fn(|i| p + i.min(m - 1));
                let out = cells4(cells, page, uv, lanes.map(|i| (chunk[i].u, chunk[i].v)));
                // All four lanes (a copy of a run-time length was a call
                // to memcpy, 8 % of the time): those past the run are
                // written again by the next run, or lie past the chunk.
                slots[p..p + 4].copy_from_slice(&out);
                // The four cells' entries, loaded together (their misses
                // overlap; an entry is 4.5 texels from its neighbour's).
                let e = out.map(|slot| {
                    if slot < LAND {
                        cells.entries[slot]
                    } else {
                        EMPTY_ENTRY
                    }
                });
                entries[p..p + 4].copy_from_slice(&e);
                p += m;
            }
        }
    }

    /// Adds the chunk's pixels to the sums, in order: a pixel whose cell
    /// is its surface's and unsplit adds to that cell's patch; the rest
    /// land by [`Surfaces::land`] (a cell of another chart, a split one).
    #[inline(always)]
    fn add(
        &mut self,
        face: &Face,
        chunk: &[Pixel],
        slots: &[usize; BATCH + 3],
        owners: &[u32; BATCH],
        entries: &[u64; BATCH + 3],
        weights: &[f32],
    ) {
        let (s, eye) = (self.s, self.eye);
        let mut escaped = 0u64;
        // In locals, so that the loop keeps them in registers.
        let mut stats = std::mem::take(&mut self.stats);
        let mut count = self.count;
        let (sums, touched) = (&mut self.sums[..], &mut self.touched[..]);
        for (k, px) in chunk.iter().enumerate() {
            let e = entries[k];
            let j = match slots[k] {
                ESCAPED => {
                    escaped += 1;
                    continue;
                }
                BACK_FACE => {
                    stats.back_faces += 1;
                    continue;
                }
                _ if e != EMPTY_ENTRY && (e >> 32) as u32 == owners[k] && e as u32 != SPLIT => {
                    e as u32
                }
                _ => {
                    let p0 = s.geometry.p_ws[px.tri as usize][0];
                    let dir = (p0 - eye).normalize_or(face.forward);
                    match s.land(px.tri, px.u, px.v, dir) {
                        Landing::Texel(tx) => s.patches.of_texel[tx as usize].0,
                        Landing::BackFace => {
                            stats.back_faces += 1;
                            continue;
                        }
                        _ => {
                            stats.unmapped += 1;
                            continue;
                        }
                    }
                }
            };
            // No branch on whether the patch is new: it was mispredicted
            // on a furnace's first pixels of each patch.
            let sum = sums[j as usize];
            touched[count] = j;
            count += usize::from(sum == 0.0);
            sums[j as usize] = sum + weights[k];
        }
        stats.escaped += escaped;
        self.stats = stats;
        self.count = count;
    }

    /// The row, sorted by column, and its counters. Where the patches seen
    /// are an eighth of all or more (in a closed room, most of them: the
    /// furnace's rows hold 70 % of its 20,184 patches), one pass over the
    /// dense sums in column order replaces sorting them (O(t log t), 6 %
    /// of the furnace's form factors): the same row, as every sum seen is
    /// positive (the delta form factors are).
    pub(crate) fn finish(mut self) -> (Vec<(u32, f32)>, FormFactorStats) {
        self.touched.truncate(self.count);
        let out = if self.touched.len() * 8 >= self.sums.len() {
            // Sized before: a collect of a filter grew the row as it went.
            let mut out = Vec::with_capacity(self.touched.len());
            for (j, &v) in self.sums.iter().enumerate() {
                if v != 0.0 {
                    out.push((j as u32, v));
                }
            }
            out
        } else {
            self.touched.sort_unstable();
            (self.touched.iter())
                .map(|&j| (j, self.sums[j as usize]))
                .collect()
        };
        (out, self.stats)
    }
}

/// Row i of F by the hemicube, sorted by column.
pub fn row(s: &Surfaces, setup: &Setup, i: usize) -> (Vec<(u32, f32)>, FormFactorStats) {
    let Some(cams) = cameras(s, i) else {
        return (Vec::new(), FormFactorStats::default());
    };
    let n = setup.cube.n;
    let mut resolve = Resolve::new(s, setup, cams.eye);
    let mut buf = vec![EMPTY; (n * n) as usize];
    for face in &cams.faces {
        let rows = if face.side { n / 2 } else { n };
        let pixels = (n * rows) as usize;
        buf[..pixels].fill(EMPTY);
        rasterize_face(s, cams.eye, face, n, &mut buf[..pixels]);
        resolve.face(face, &buf[..pixels]);
    }
    resolve.finish()
}

/// Rows of F (sorted by column) with their counters, in patch order.
pub type Rows = Vec<(Vec<(u32, f32)>, FormFactorStats)>;

/// Rows of F by hemicubes rendered elsewhere, a batch of patches at a
/// time: the GPU's ([`super::gpu_hemicube`]).
pub trait RowBatches: Sync {
    /// Rows (sorted by column) of `patches`, in their order.
    ///
    /// # Errors
    /// The device failed; the caller computes the rows on the CPU.
    fn rows(&self, s: &Surfaces, setup: &Setup, patches: &[usize]) -> crate::Result<Rows>;
    /// The device, for the bake's warning.
    fn describe(&self) -> String;
}

/// Every row of F from `gpu`, a pass of hemicubes at a time.
///
/// # Errors
/// As [`RowBatches::rows`].
pub fn compute_on(
    s: &Surfaces,
    gpu: &dyn RowBatches,
    n: u32,
    advance: &(dyn Fn(u64) + Sync),
) -> crate::Result<FormFactors> {
    let setup = Setup::new(s, n);
    let patches: Vec<usize> = (0..s.patches.len()).collect();
    let mut results = Vec::with_capacity(patches.len());
    for chunk in patches.chunks(4096) {
        results.extend(gpu.rows(s, &setup, chunk)?);
        advance(chunk.len() as u64);
    }
    Ok(FormFactors::from_results(patches.len(), results))
}

/// Every row of F by the hemicube at resolution `n`.
pub fn compute(s: &Surfaces, n: u32, advance: &(dyn Fn(u64) + Sync)) -> FormFactors {
    let setup = Setup::new(s, n);
    FormFactors::from_row_fn(s.patches.len(), |i| row(s, &setup, i), advance)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The delta form factors integrate the cosine-weighted hemisphere:
    /// top 0.554126, each half side 0.111468, all together 1.
    #[test]
    fn delta_form_factors_sum_to_one() {
        let c = Hemicube::new(256);
        let top: f64 = c.top.iter().map(|&v| v as f64).sum();
        let side: f64 = c.side.iter().map(|&v| v as f64).sum();
        assert!((top - 0.554126).abs() < 1e-4, "{top}");
        assert!((side - 0.111468).abs() < 1e-4, "{side}");
        assert!((top + 4.0 * side - 1.0).abs() < 2e-4);
    }

    #[test]
    fn raster_covers_square_once() {
        let n = 8;
        let mut buf = vec![EMPTY; 64];
        let a = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(8.0, 0.0, 1.0),
            Vec3::new(8.0, 8.0, 1.0),
        ];
        let b = [
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(8.0, 8.0, 2.0),
            Vec3::new(0.0, 8.0, 2.0),
        ];
        let with = |v: [Vec3; 3]| [(v[0], Vec2::ZERO), (v[1], Vec2::X), (v[2], Vec2::Y)];
        let (a, b) = (with(a), with(b));
        raster_triangle(&a, 0, n, n, &mut buf);
        raster_triangle(&b, 1, n, n, &mut buf);
        assert!(
            buf.iter().all(|p| p.tri != u32::MAX),
            "a gap between two triangles"
        );
        // Nearer triangle wins where both cover (the diagonal pixels).
        assert_eq!(buf[7 * 8 + 7].tri, 0);
    }

    /// Four pixels at a time or one: every pixel a triangle writes holds
    /// the one-pixel arithmetic's depth and weights to the bit, and every
    /// pixel it leaves is one that arithmetic finds outside.
    #[test]
    fn lanes_give_the_scalar_bits() {
        let n = 37;
        let mut rng = crate::util::sampling::Stream::new(3, 0, 0);
        for _ in 0..200 {
            let mut corner = || {
                let mut c = || rng.next_f32() * 50.0 - 6.0;
                (Vec3::new(c(), c(), 0.5 + c().abs()), Vec2::new(c(), c()))
            };
            let v = [corner(), corner(), corner()];
            let mut buf = vec![EMPTY; (n * n) as usize];
            raster_triangle(&v, 7, n, n, &mut buf);
            let (a, b, c) = (v[0].0, v[1].0, v[2].0);
            let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
            let edge =
                |a: Vec3, b: Vec3, p: Vec2| (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
            let inv_z = [1.0 / a.z, 1.0 / b.z, 1.0 / c.z];
            let bary_z = [v[0].1 * inv_z[0], v[1].1 * inv_z[1], v[2].1 * inv_z[2]];
            for (k, px) in buf.iter().enumerate() {
                let p = Vec2::new((k as u32 % n) as f32 + 0.5, (k as u32 / n) as f32 + 0.5);
                // As `raster_triangle` computes it (the weights through
                // 1 / area, then the depth and the perspective weights).
                let inv_area = 1.0 / area;
                let (w0, w1) = (edge(b, c, p) * inv_area, edge(c, a, p) * inv_area);
                let w2 = 1.0 - w0 - w1;
                let inside = area.abs() >= 1e-12 && !(w0 < 0.0 || w1 < 0.0 || w2 < 0.0);
                assert_eq!(px.tri != u32::MAX, inside, "pixel {k}: written iff inside");
                if !inside {
                    continue;
                }
                let depth = 1.0 / (w0 * inv_z[0] + w1 * inv_z[1] + w2 * inv_z[2]);
                let uv = (bary_z[0] * w0 + bary_z[1] * w1 + bary_z[2] * w2) * depth;
                assert_eq!(px.depth.to_bits(), depth.to_bits());
                assert_eq!(
                    (px.u.to_bits(), px.v.to_bits()),
                    (uv.x.to_bits(), uv.y.to_bits())
                );
            }
        }
    }

    /// [`cells4`] finds the cell that one pixel's arithmetic finds
    /// (`Geometry::uv_lm_at`, then ⌊·⌋ and the page's bounds), for
    /// positions inside, on and around the page, negative ones, NaN and
    /// ones past `i32`'s range.
    #[test]
    fn four_cells_at_a_time_are_the_scalar_cells() {
        let cells = CellPatches {
            entries: Vec::new(),
            width: 13,
            height: 9,
        };
        let page = cells.page_start(2);
        let one = |t: &[Vec2; 3], u: f32, v: f32| -> usize {
            let p = t[0] * (1.0 - u - v) + t[1] * u + t[2] * v;
            let (x, y) = (p.x.floor() as f64, p.y.floor() as f64);
            if (0.0..13.0).contains(&x) && (0.0..9.0).contains(&y) {
                page + y as usize * 13 + x as usize
            } else {
                LAND
            }
        };
        let mut rng = crate::util::sampling::Stream::new(5, 0, 0);
        let odd = [f32::NAN, 3e9, -3e9, -0.0, 13.0, 9.0, -1e-7, 12.999_999];
        let mut checked = 0;
        for round in 0..2000 {
            let mut c = |k: usize| {
                if round % 7 == 0 && k < odd.len() {
                    odd[k]
                } else {
                    rng.next_f32() * 20.0 - 4.0
                }
            };
            let t = [
                Vec2::new(c(0), c(1)),
                Vec2::new(c(2), c(3)),
                Vec2::new(c(4), c(5)),
            ];
            let uv: [(f32, f32); 4] = std::array::from_fn(|_| (rng.next_f32(), rng.next_f32()));
            let got = cells4(&cells, page, &t, uv);
            for (k, &(u, v)) in uv.iter().enumerate() {
                assert_eq!(got[k], one(&t, u, v), "round {round}, lane {k}");
                checked += usize::from(got[k] != LAND);
            }
        }
        assert!(checked > 1000, "most lanes land on the page ({checked})");
    }
}
