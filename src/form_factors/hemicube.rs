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

use super::raycast::{Landing, Surfaces};
use super::{FormFactorStats, FormFactors};
use crate::sampling::{frame, offset_ray_origin};
use glam::{Vec2, Vec3};

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
struct Face {
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    /// Side faces cover only up ∈ [0, 1] (rows `0..n/2` of the up axis).
    side: bool,
}

/// A rasterised pixel: closest depth and triangle.
#[derive(Clone, Copy)]
struct Pixel {
    depth: f32,
    tri: u32,
}

const EMPTY: Pixel = Pixel {
    depth: f32::INFINITY,
    tri: u32::MAX,
};

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
        let mut poly: Vec<Vec3> = cam.to_vec();
        let mut next: Vec<Vec3> = Vec::with_capacity(9);
        for pl in planes {
            next.clear();
            let d = |c: Vec3| pl.truncate().dot(c) + pl.w;
            for k in 0..poly.len() {
                let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
                let (da, db) = (d(a), d(b));
                if da >= 0.0 {
                    next.push(a);
                }
                if (da >= 0.0) != (db >= 0.0) {
                    next.push(a + (b - a) * (da / (da - db)));
                }
            }
            std::mem::swap(&mut poly, &mut next);
            if poly.len() < 3 {
                break;
            }
        }
        let len = poly.len();
        if len < 3 {
            continue;
        }
        let scr: Vec<Vec3> = poly.iter().map(|&c| to_screen(c)).collect();
        for k in 1..len - 1 {
            raster_triangle(&[scr[0], scr[k], scr[k + 1]], t as u32, n, rows, buf);
        }
    }
}

/// Edge-function rasterisation of one screen-space triangle (x, y in pixels,
/// z = view depth) with a depth test on 1/z interpolated linearly.
fn raster_triangle(v: &[Vec3; 3], tri: u32, n: u32, rows: u32, buf: &mut [Pixel]) {
    let area = (v[1].x - v[0].x) * (v[2].y - v[0].y) - (v[1].y - v[0].y) * (v[2].x - v[0].x);
    if area.abs() < 1e-12 {
        return;
    }
    let min_x = v
        .iter()
        .map(|p| p.x)
        .fold(f32::INFINITY, f32::min)
        .floor()
        .max(0.0) as i64;
    let max_x = v
        .iter()
        .map(|p| p.x)
        .fold(f32::NEG_INFINITY, f32::max)
        .ceil()
        .min(n as f32) as i64;
    let min_y = v
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min)
        .floor()
        .max(0.0) as i64;
    let max_y = v
        .iter()
        .map(|p| p.y)
        .fold(f32::NEG_INFINITY, f32::max)
        .ceil()
        .min(rows as f32) as i64;
    let inv_z = v.map(|p| 1.0 / p.z);
    let edge = |a: Vec3, b: Vec3, p: Vec2| (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
    for y in min_y..max_y {
        for x in min_x..max_x {
            let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let w0 = edge(v[1], v[2], p) / area;
            let w1 = edge(v[2], v[0], p) / area;
            let w2 = 1.0 - w0 - w1;
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            let iz = w0 * inv_z[0] + w1 * inv_z[1] + w2 * inv_z[2];
            let depth = 1.0 / iz;
            let px = &mut buf[(y as u32 * n + x as u32) as usize];
            if depth < px.depth {
                *px = Pixel { depth, tri };
            }
        }
    }
}

/// Row i of F by the hemicube, sorted by column.
pub fn row(s: &Surfaces, cube: &Hemicube, i: usize) -> (Vec<(u32, f32)>, FormFactorStats) {
    if s.patch_buried(i) {
        return (Vec::new(), FormFactorStats::default());
    }
    let n = cube.n;
    let nrm = s.patches.n_ws[i];
    // Eye: the patch centroid pulled onto its nearest texel's surface, off it by an offset.
    let eye_surface = s.patches.p_ws[i];
    let eye =
        offset_ray_origin(eye_surface, nrm) + nrm * 1e-5 * (1.0 + eye_surface.abs().max_element());
    let (t, b) = frame(nrm);
    let faces = [
        Face {
            right: t,
            up: b,
            forward: nrm,
            side: false,
        },
        Face {
            right: -b,
            up: nrm,
            forward: t,
            side: true,
        },
        Face {
            right: b,
            up: nrm,
            forward: -t,
            side: true,
        },
        Face {
            right: t,
            up: nrm,
            forward: b,
            side: true,
        },
        Face {
            right: -t,
            up: nrm,
            forward: -b,
            side: true,
        },
    ];
    let mut stats = FormFactorStats::default();
    let mut acc: Vec<(u32, f32)> = Vec::new();
    let mut buf = vec![EMPTY; (n * n) as usize];
    for face in &faces {
        let rows = if face.side { n / 2 } else { n };
        let pixels = (n * rows) as usize;
        buf[..pixels].fill(EMPTY);
        rasterize_face(s, eye, face, n, &mut buf[..pixels]);
        let weights = if face.side { &cube.side } else { &cube.top };
        let up_min = if face.side { 0.0 } else { -1.0 };
        for y in 0..rows {
            for x in 0..n {
                let k = (y * n + x) as usize;
                let px = buf[k];
                let w = weights[k];
                stats.rays += 1;
                if px.tri == u32::MAX {
                    stats.escaped += 1;
                    continue;
                }
                // Resolve the visible point exactly: the pixel's ray against its triangle.
                let sx = -1.0 + (x as f32 + 0.5) * 2.0 / n as f32;
                let sy = up_min + (y as f32 + 0.5) * 2.0 / n as f32;
                let dir = (face.right * sx + face.up * sy + face.forward).normalize();
                match s.resolve(px.tri, eye, dir) {
                    Landing::Texel(tx) => acc.push((s.patches.of_texel[tx as usize].0, w)),
                    Landing::BackFace => stats.back_faces += 1,
                    _ => stats.unmapped += 1,
                }
            }
        }
    }
    acc.sort_unstable_by_key(|e| e.0);
    let mut out: Vec<(u32, f32)> = Vec::new();
    for (j, w) in acc {
        match out.last_mut() {
            Some((c, f)) if *c == j => *f += w,
            _ => out.push((j, w)),
        }
    }
    (out, stats)
}

/// Every row of F by the hemicube at resolution `n`.
pub fn compute(s: &Surfaces, n: u32, advance: &(dyn Fn(u64) + Sync)) -> FormFactors {
    let cube = Hemicube::new(n);
    FormFactors::from_row_fn(s.patches.len(), |i| row(s, &cube, i), advance)
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
        raster_triangle(&a, 0, n, n, &mut buf);
        raster_triangle(&b, 1, n, n, &mut buf);
        assert!(
            buf.iter().all(|p| p.tri != u32::MAX),
            "a gap between two triangles"
        );
        // Nearer triangle wins where both cover (the diagonal pixels).
        assert_eq!(buf[7 * 8 + 7].tri, 0);
    }
}
