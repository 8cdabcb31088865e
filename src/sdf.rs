//! The signed distance field of the level (issue #24): a regular grid of
//! voxels over the scene's bounds, each holding the distance in metres
//! from its centre to the nearest world triangle, positive in free space
//! and negative inside solids (behind one-sided faces). Games march it for
//! soft shadows and ambient occlusion on moving objects (Hart 1996,
//! "Sphere tracing"; Unreal's distance-field shadows and DFAO).
//!
//! - **Distance**: exact and unsigned, one closest-point query per voxel on
//!   the ray caster's BVH ([`RayCaster::closest_point`]), bounded by the
//!   narrow band where one is asked for. Triangles the ray caster leaves
//!   out (`cast_shadows: false`) are left out here too; alpha-masked ones
//!   count whole (their cut-outs are not consulted).
//! - **Sign**: where the nearest point lies inside a one-sided triangle
//!   (not on an edge), the side of that triangle the voxel is on: behind
//!   it is inside (the pseudo-normal rule of Bærentzen & Aanæs 2005,
//!   exact on a face). Elsewhere (nearest on an edge or a vertex, or on a
//!   double-sided material) by ray voting against one-sided faces, as
//!   Unreal's mesh distance fields do: rays from the voxel's centre in a
//!   fixed spherical Fibonacci set; a ray that first meets the back of a
//!   one-sided face votes *inside*, one that meets a front face, a
//!   double-sided material's face, or nothing votes *outside*; more than
//!   half inside votes is inside. Unreal takes a quarter; a half is the
//!   right rule for the open meshes of real levels, where a point in front
//!   of an opening sees back faces through it about as often as a point
//!   behind it sees the sky. (Ray voting rather than generalised winding
//!   numbers, Jacobson et al. 2013: the BVH answers rays in O(log n), and
//!   a level's one-sided walls enclose nothing a winding number could
//!   count.) Where the first 8 votes are not clear (a quarter to three
//!   quarters inside), 24 more are cast. So a one-sided wall is a surface
//!   the field crosses (negative behind it), and sphere tracing finds it
//!   at the zero crossing.
//!
//! Deterministic: every voxel's rays are fixed.

pub mod agreement;

use crate::geometry::Geometry;
use crate::raycast::RayCaster;
use crate::scene::Scene;
use glam::Vec3;
use rayon::prelude::*;

/// Votes cast first, and the extra ones where those are not clear.
const VOTES: u32 = 8;
const MORE_VOTES: u32 = 24;
/// Most voxels a field may have (64 Mi: ~1.5 GiB while baking, 256 MiB
/// of field).
pub const MAX_VOXELS: u64 = 64 << 20;

/// The grid: where it is and how fine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// World position of voxel (0, 0, 0)'s minimum corner.
    pub origin: Vec3,
    /// Voxel edge (metres).
    pub voxel: f32,
    /// Voxels along x, y, z.
    pub dims: [u32; 3],
}

impl Grid {
    /// A grid over `bounds` (min, max) with voxels of edge `voxel`, one
    /// voxel of margin on every side.
    pub fn over(bounds: (Vec3, Vec3), voxel: f32) -> Grid {
        let (lo, hi) = (bounds.0 - Vec3::splat(voxel), bounds.1 + Vec3::splat(voxel));
        let n = ((hi - lo) / voxel).ceil().max(Vec3::ONE);
        Grid {
            origin: lo,
            voxel,
            dims: [n.x as u32, n.y as u32, n.z as u32],
        }
    }

    /// Voxels in all.
    pub fn len(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }

    /// True when the grid has no voxel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Voxel `i`'s (x, y, z); x fastest.
    pub fn xyz(&self, i: usize) -> [u32; 3] {
        let [nx, ny, _] = self.dims.map(|d| d as usize);
        [
            (i % nx) as u32,
            ((i / nx) % ny) as u32,
            (i / (nx * ny)) as u32,
        ]
    }

    /// Voxel `i`'s centre (world).
    pub fn centre(&self, i: usize) -> Vec3 {
        let [x, y, z] = self.xyz(i);
        self.origin + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * self.voxel
    }
}

/// The signed distance field.
#[derive(Clone, Debug)]
pub struct Sdf {
    /// The grid.
    pub grid: Grid,
    /// Signed distance per voxel (metres; x fastest, then y, then z),
    /// clamped to ± the narrow band where there is one.
    pub distance: Vec<f32>,
    /// Rays cast for the signs.
    pub rays: u64,
}

impl Sdf {
    /// Sign flips in open air: pairs of neighbouring voxels, both more
    /// than `clear` voxels from any surface, whose signs differ. The field
    /// changes sign only across a surface, so a field of closed solids
    /// has none (returns the flips and the pairs counted).
    pub fn open_air_flips(&self, clear: f32) -> (u64, u64) {
        let [nx, ny, nz] = self.grid.dims.map(|d| d as usize);
        let far = clear * self.grid.voxel;
        let d = &self.distance;
        let (mut flips, mut pairs) = (0u64, 0u64);
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let i = x + nx * (y + ny * z);
                    if d[i].abs() <= far {
                        continue;
                    }
                    for (ok, j) in [
                        (x + 1 < nx, i + 1),
                        (y + 1 < ny, i + nx),
                        (z + 1 < nz, i + nx * ny),
                    ] {
                        if ok && d[j].abs() > far {
                            pairs += 1;
                            flips += ((d[i] < 0.0) != (d[j] < 0.0)) as u64;
                        }
                    }
                }
            }
        }
        (flips, pairs)
    }

    /// The field at world point `p`, trilinear between voxel centres
    /// (clamped at the grid's border).
    pub fn sample(&self, p: Vec3) -> f32 {
        let g = &self.grid;
        let f = (p - g.origin) / g.voxel - 0.5;
        let max = Vec3::new(g.dims[0] as f32, g.dims[1] as f32, g.dims[2] as f32) - 1.0;
        let f = f.clamp(Vec3::ZERO, max);
        let i = f.floor().min(max - 1.0).max(Vec3::ZERO);
        let w = f - i;
        let (x, y, z) = (i.x as usize, i.y as usize, i.z as usize);
        let [nx, ny, _] = g.dims.map(|d| d as usize);
        let at = |dx: usize, dy: usize, dz: usize| {
            let (xx, yy, zz) = (
                (x + dx).min(nx - 1),
                (y + dy).min(ny - 1),
                (z + dz).min(g.dims[2] as usize - 1),
            );
            self.distance[xx + nx * (yy + ny * zz)]
        };
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let c00 = lerp(at(0, 0, 0), at(1, 0, 0), w.x);
        let c10 = lerp(at(0, 1, 0), at(1, 1, 0), w.x);
        let c01 = lerp(at(0, 0, 1), at(1, 0, 1), w.x);
        let c11 = lerp(at(0, 1, 1), at(1, 1, 1), w.x);
        lerp(lerp(c00, c10, w.y), lerp(c01, c11, w.y), w.z)
    }

    /// Sphere tracing (Hart 1996): march `origin + t·dir` (`dir` unit) by
    /// the field's distance less half a voxel (trilinear interpolation
    /// between voxel centres reads up to half a voxel too far at a
    /// zero-thickness sheet, whose two sides are both positive), at least
    /// a twentieth of a voxel a step. Within 0.6 voxel of a surface it
    /// walks on in tenths of a voxel to where the field crosses zero (a
    /// solid's surface; linear between the two steps) or stops falling (a
    /// sheet): the hit's t. The march starts where the ray enters the
    /// grid; None where it leaves the grid or passes `tmax` first. At most
    /// 2048 steps.
    pub fn march(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<f32> {
        let g = &self.grid;
        let size = Vec3::new(g.dims[0] as f32, g.dims[1] as f32, g.dims[2] as f32) * g.voxel;
        let (lo, hi) = (g.origin, g.origin + size);
        // Where the ray is inside the grid's box (slabs).
        let inv = dir.recip();
        let (ta, tb) = ((lo - origin) * inv, (hi - origin) * inv);
        let enter = ta.min(tb).max_element().max(0.0);
        let leave = ta.max(tb).min_element().min(tmax);
        if enter > leave {
            return None;
        }
        let mut t = enter;
        for _ in 0..2048 {
            if t > leave {
                return None;
            }
            let p = origin + dir * t;
            let d = self.sample(p);
            if d < 0.6 * g.voxel {
                return Some(self.refine(origin, dir, t, d));
            }
            t += (d - 0.5 * g.voxel).max(0.05 * g.voxel);
        }
        None
    }

    /// From `t` (field `d`) near a surface, tenth-voxel steps to the
    /// field's zero crossing or its minimum along the ray (at most 30).
    fn refine(&self, origin: Vec3, dir: Vec3, mut t: f32, mut d: f32) -> f32 {
        let step = 0.1 * self.grid.voxel;
        if d <= 0.0 {
            return t;
        }
        for _ in 0..30 {
            let next = self.sample(origin + dir * (t + step));
            if next <= 0.0 {
                return t + step * d / (d - next);
            }
            if next >= d {
                return t;
            }
            (t, d) = (t + step, next);
        }
        t
    }
}

/// What to bake.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Voxel edge in metres.
    pub voxel: f32,
    /// Clamp distances at this many voxels (None: exact everywhere).
    pub band: Option<f32>,
}

/// The voxel edge that gives `resolution` voxels along the longest side
/// of `bounds`.
pub fn voxel_for_resolution(bounds: (Vec3, Vec3), resolution: u32) -> f32 {
    (bounds.1 - bounds.0).max_element().max(1e-6) / resolution.max(1) as f32
}

/// Bakes the field of `geometry` (its triangles as `rays` holds them).
pub fn bake(scene: &Scene, geometry: &Geometry, rays: &RayCaster, settings: Settings) -> Sdf {
    let bounds = geometry.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
    let grid = Grid::over(bounds, settings.voxel);
    let band = settings.band.map(|b| b * settings.voxel);
    let nearest = distances(&grid, rays, band);
    let (inside, cast) = signs(scene, geometry, rays, &grid, &nearest);
    let distance = nearest
        .iter()
        .zip(&inside)
        .map(|(n, &inside)| if inside { -n.0 } else { n.0 })
        .collect();
    Sdf {
        grid,
        distance,
        rays: cast,
    }
}

/// The nearest triangle of a voxel's centre: (distance, triangle, point).
type Nearest = (f32, u32, Vec3);

/// Step 1: the unsigned distance of every voxel's centre (clamped to
/// `band`), with its nearest triangle and point (`u32::MAX` beyond the
/// band).
fn distances(grid: &Grid, rays: &RayCaster, band: Option<f32>) -> Vec<Nearest> {
    let max_d2 = band.map_or(f32::INFINITY, |b| b * b);
    (0..grid.len())
        .into_par_iter()
        .map(|i| {
            let p = grid.centre(i);
            rays.closest_point(p, max_d2)
                .map_or((band.unwrap_or(f32::INFINITY), u32::MAX, p), |(t, d, q)| {
                    (d, t, q)
                })
        })
        .collect()
}

/// The sign the nearest point gives by itself, where it can: a nearest
/// point inside a one-sided triangle (not on its edges) is on the side of
/// `p` that the triangle's normal says, so `p` is inside where it lies
/// behind it (the pseudo-normal rule of Bærentzen & Aanæs 2005, on a
/// face). None on an edge or a vertex, on a double-sided face, or right
/// on the surface: those vote.
fn face_sign(scene: &Scene, g: &Geometry, p: Vec3, (d, tri, q): Nearest) -> Option<bool> {
    if tri == u32::MAX || d <= 1e-6 {
        return None;
    }
    let t = tri as usize;
    if scene.materials[g.material[t] as usize].double_sided {
        return None;
    }
    // On an edge or a vertex (or a degenerate triangle, (0, 0)): no sign.
    let (u, v) = g.barycentrics(tri, q);
    if [1.0 - u - v, u, v].iter().any(|&w| w < 1e-4) {
        return None;
    }
    Some((p - q).dot(g.ng_ws[t]) < 0.0)
}

/// Step 2: each voxel's sign: [`face_sign`] where it gives one, else by
/// its votes ([`votes`]): inside where more than half say so. Returns the
/// signs and the rays cast.
fn signs(
    scene: &Scene,
    g: &Geometry,
    rays: &RayCaster,
    grid: &Grid,
    nearest: &[Nearest],
) -> (Vec<bool>, u64) {
    let out: Vec<(bool, u64)> = (0..grid.len())
        .into_par_iter()
        .map(|i| {
            let p = grid.centre(i);
            if let Some(inside) = face_sign(scene, g, p, nearest[i]) {
                return (inside, 0);
            }
            let (inside, total, cast) = votes(scene, g, rays, p);
            (2 * inside > total, cast)
        })
        .collect();
    let cast = out.iter().map(|o| o.1).sum();
    (out.into_iter().map(|o| o.0).collect(), cast)
}

/// The sign votes at `p`: (inside votes, votes, rays cast). [`VOTES`]
/// rays of a spherical Fibonacci set, and [`MORE_VOTES`] more where a
/// quarter to three quarters of the first ones said inside.
fn votes(scene: &Scene, g: &Geometry, rays: &RayCaster, p: Vec3) -> (u32, u32, u64) {
    let vote = |d: Vec3| -> bool {
        let Some(hit) = rays.closest_hit(p, d, f32::INFINITY) else {
            return false;
        };
        let tri = hit.tri as usize;
        g.ng_ws[tri].dot(d) > 0.0 && !scene.materials[g.material[tri] as usize].double_sided
    };
    let first = (0..VOTES)
        .filter(|&k| vote(crate::probes::light::fibonacci(k, VOTES)))
        .count() as u32;
    if 4 * first < VOTES || 4 * first > 3 * VOTES {
        return (first, VOTES, VOTES as u64);
    }
    let more = (0..MORE_VOTES)
        .filter(|&k| vote(crate::probes::light::fibonacci(k, MORE_VOTES)))
        .count() as u32;
    (
        first + more,
        VOTES + MORE_VOTES,
        (VOTES + MORE_VOTES) as u64,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_covers_the_bounds_with_a_margin() {
        let g = Grid::over((Vec3::ZERO, Vec3::new(1.0, 2.0, 0.5)), 0.25);
        assert_eq!(g.dims, [6, 10, 4]);
        assert_eq!(g.origin, Vec3::splat(-0.25));
        assert_eq!(g.xyz(6 * 10 + 6 + 1), [1, 1, 1]);
        assert!((g.centre(0) - Vec3::splat(-0.125)).length() < 1e-6);
    }
}
