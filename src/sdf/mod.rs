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
//!   exact on a face), except that a voxel in front of its nearest face
//!   casts one ray along that face's normal, and votes where the ray
//!   meets the back of a one-sided face (it is enclosed over the face: a
//!   solid without a bottom face standing on a floor). Elsewhere (nearest
//!   on an edge or a vertex, or on a double-sided material) by ray voting
//!   against one-sided faces, as Unreal's mesh distance fields do: rays from the voxel's centre in a
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
//! The grid covers the scene's bounds, or the union of its probe volumes'
//! boxes ([`bounds`], [`SdfBounds`]): where dynamic objects go.
//!
//! Deterministic: every voxel's rays are fixed.

pub mod agreement;

use crate::config::SdfBounds;
use crate::layout::geometry::Geometry;
use crate::raycast::RayCaster;
use crate::scene::Scene;
use glam::Vec3;
use rayon::prelude::*;

/// Votes cast first, and the extra ones where those are not clear.
const VOTES: u32 = 8;
const MORE_VOTES: u32 = 24;
/// [`Sdf::march`]'s most steps.
pub const MARCH_STEPS: u32 = 4096;
/// [`Sdf::march`]'s least step (voxels).
pub const MIN_STEP: f32 = 0.25;
/// The longest gradient (and slope along the ray) of a zero crossing that
/// [`Sdf::march`] takes for a surface.
pub const SURFACE_SLOPE: f32 = 1.3;
/// [`Sdf::march`] looks for an unsigned surface at minima of |field|
/// below this (voxels)...
pub const NEAR: f32 = 0.75;
/// ... and takes one under this (voxels) for a surface...
pub const UNSIGNED: f32 = 0.25;
/// ... or one under this (voxels) where the field's gradient is under
/// [`FLAT`].
pub const UNSIGNED_FLAT: f32 = 0.51;
/// See [`UNSIGNED_FLAT`].
pub const FLAT: f32 = 0.5;
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

    /// Sphere tracing (Hart 1996) of `origin + t·dir` (`dir` unit), from
    /// where the ray enters the grid to where it leaves it or passes
    /// `tmax` (None: no hit). At most [`MARCH_STEPS`] steps.
    ///
    /// - **Steps** of the field's |distance| less half a voxel (trilinear
    ///   interpolation between voxel centres reads up to half a voxel too
    ///   far at a zero-thickness sheet, whose two sides are both
    ///   positive), at least [`MIN_STEP`] voxel.
    /// - **A hit is a sign change** between two steps, bracketed and
    ///   bisected to the zero crossing ([`Sdf::crossing`]), where the
    ///   field's gradient is about a unit vector, as a distance's is at a
    ///   surface. A sign flip in open air (two voxels a distance D from
    ///   any surface, of opposite signs) has a gradient of 2D / voxel and
    ///   is marched through. Either way round: a ray from behind a
    ///   one-sided face meets it where the field turns positive. So a ray
    ///   that passes near a surface without crossing it goes on (the old
    ///   rule, stopping within 0.6 voxel of any surface, stopped 1.8 % of
    ///   the Cornell box's rays at edges and walls they run along).
    /// - **Unsigned surfaces**: a double-sided face, two one-sided faces
    ///   back to back, a solid thinner than a voxel have no sign change
    ///   (positive on both sides). Where |field| has a local minimum among
    ///   the steps below [`NEAR`] voxel, a golden-section search between
    ///   the neighbouring steps finds it ([`Sdf::minimum`]): a hit there
    ///   when it is under [`UNSIGNED`] voxel, or under [`UNSIGNED_FLAT`]
    ///   voxel where the field's gradient is under [`FLAT`] (the flat
    ///   bottom between voxel centres on either side of a sheet: there
    ///   the two sides' gradients cancel, where beside a surface that the
    ///   ray passes the gradient stays about a unit vector). A minimum
    ///   below zero is a thin negative region the steps went over: a sign
    ///   change as above. A ray that passes within a quarter voxel of a
    ///   surface without meeting it stops there: at the field's
    ///   resolution, that is a thin sheet. Not where the field is steeper
    ///   than [`SURFACE_SLOPE`] there: that dip is the edge of a sign flip
    ///   in open air, not a surface.
    ///
    /// Deterministic (no randomness; the same samples for the same ray).
    pub fn march(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<f32> {
        let v = self.grid.voxel;
        let (enter, leave) = self.span(origin, dir, tmax)?;
        let at = |t: f32| self.sample(origin + dir * t);
        let (mut t, mut d) = (enter, at(enter));
        // The step before (t, d).
        let mut before: Option<(f32, f32)> = None;
        for _ in 0..MARCH_STEPS {
            if t >= leave {
                return None;
            }
            let next_t = (t + (d.abs() - 0.5 * v).max(MIN_STEP * v)).min(leave);
            let next_d = at(next_t);
            if (d < 0.0) != (next_d < 0.0) {
                if let Some(hit) = self.crossing(origin, dir, (t, d), (next_t, next_d)) {
                    return Some(hit);
                }
            } else if let Some((tb, db)) = before.filter(|&(_, db)| {
                (db < 0.0) == (d < 0.0)
                    && d.abs() < NEAR * v
                    && d.abs() < db.abs()
                    && d.abs() <= next_d.abs()
            }) {
                if let Some(hit) = self.unsigned(origin, dir, (tb, db), d.signum(), next_t) {
                    return Some(hit);
                }
            }
            before = Some((t, d));
            (t, d) = (next_t, next_d);
        }
        None
    }

    /// At a local minimum of |field| between step `a` (t, field) and
    /// `tb`, on the side `s` (±1) of the field: the hit there, if any
    /// (see [`Sdf::march`]).
    fn unsigned(&self, origin: Vec3, dir: Vec3, a: (f32, f32), s: f32, tb: f32) -> Option<f32> {
        let v = self.grid.voxel;
        let (tm, dm) = self.minimum(origin, dir, s, a.0, tb);
        if dm * s < 0.0 {
            return self.crossing(origin, dir, a, (tm, dm));
        }
        if dm.abs() >= UNSIGNED_FLAT * v {
            return None;
        }
        let slope = self.gradient(origin + dir * tm).length();
        // Beside a sign flip (where the votes of open air change, or the
        // solid behind a one-sided face meets open air) the field is
        // steep: no surface.
        ((dm.abs() < UNSIGNED * v && slope <= SURFACE_SLOPE) || slope < FLAT).then_some(tm)
    }

    /// Where `origin + t·dir` (`t` ≥ 0) lies in the grid's box, to `tmax`.
    fn span(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<(f32, f32)> {
        let g = &self.grid;
        let size = Vec3::new(g.dims[0] as f32, g.dims[1] as f32, g.dims[2] as f32) * g.voxel;
        let (lo, hi) = (g.origin, g.origin + size);
        let inv = dir.recip();
        let (ta, tb) = ((lo - origin) * inv, (hi - origin) * inv);
        let enter = ta.min(tb).max_element().max(0.0);
        let leave = ta.max(tb).min_element().min(tmax);
        (enter <= leave).then_some((enter, leave))
    }

    /// The zero crossing between `a` and `b` (t, field; the field of
    /// opposite signs): bisected to a 32nd of a voxel, then linear. None
    /// where it is no surface: the field's slope along the ray there, or
    /// its gradient, longer than [`SURFACE_SLOPE`] (a distance's gradient
    /// is a unit vector; a sign flip's is not).
    fn crossing(&self, origin: Vec3, dir: Vec3, a: (f32, f32), b: (f32, f32)) -> Option<f32> {
        let v = self.grid.voxel;
        let ((mut ta, mut da), (mut tb, mut db)) = (a, b);
        for _ in 0..16 {
            if tb - ta <= v / 32.0 {
                break;
            }
            let tm = 0.5 * (ta + tb);
            let dm = self.sample(origin + dir * tm);
            if (dm < 0.0) == (da < 0.0) {
                (ta, da) = (tm, dm);
            } else {
                (tb, db) = (tm, dm);
            }
        }
        let sum = da.abs() + db.abs();
        if sum > SURFACE_SLOPE * (tb - ta) + 1e-3 * v {
            return None;
        }
        let t = if sum > 0.0 {
            ta + (tb - ta) * da.abs() / sum
        } else {
            ta
        };
        (self.gradient(origin + dir * t).length() <= SURFACE_SLOPE).then_some(t)
    }

    /// The field's gradient at `q`, by central differences half a voxel
    /// either side.
    fn gradient(&self, q: Vec3) -> Vec3 {
        let h = 0.5 * self.grid.voxel;
        Vec3::new(
            self.sample(q + Vec3::X * h) - self.sample(q - Vec3::X * h),
            self.sample(q + Vec3::Y * h) - self.sample(q - Vec3::Y * h),
            self.sample(q + Vec3::Z * h) - self.sample(q - Vec3::Z * h),
        ) / (2.0 * h)
    }

    /// The t in [`a`, `b`] where `s`·field is least (golden-section
    /// search, 10 steps: to 1 % of the interval), and the field there.
    fn minimum(&self, origin: Vec3, dir: Vec3, s: f32, mut a: f32, mut b: f32) -> (f32, f32) {
        const R: f32 = 0.618_034;
        let f = |t: f32| self.sample(origin + dir * t);
        let (mut c, mut e) = (b - R * (b - a), a + R * (b - a));
        let (mut fc, mut fe) = (f(c), f(e));
        for _ in 0..10 {
            if s * fc < s * fe {
                (b, e, fe) = (e, c, fc);
                c = b - R * (b - a);
                fc = f(c);
            } else {
                (a, c, fc) = (c, e, fe);
                e = a + R * (b - a);
                fe = f(e);
            }
        }
        if s * fc < s * fe {
            (c, fc)
        } else {
            (e, fe)
        }
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

/// The box a field covers ([`SdfBounds`]): the scene's bounds (its
/// triangles'), or the union of its probe volumes' world boxes
/// ([`crate::scene::probe_volume::VolumeSpec::world_bounds`]). None where there is
/// nothing to cover (no triangle, no probe volume).
pub fn bounds(scene: &Scene, geometry: &Geometry, over: SdfBounds) -> Option<(Vec3, Vec3)> {
    match over {
        SdfBounds::Scene => geometry.bounds(),
        SdfBounds::ProbeVolumes => scene
            .probe_volumes
            .iter()
            .map(|v| v.world_bounds())
            .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1))),
    }
}

/// Bakes the field of `geometry` (its triangles as `rays` holds them)
/// over the scene's bounds.
pub fn bake(scene: &Scene, geometry: &Geometry, rays: &RayCaster, settings: Settings) -> Sdf {
    let bounds = geometry.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
    bake_over(scene, geometry, rays, bounds, settings)
}

/// Bakes the field over `bounds` (min, max; [`Grid::over`] adds a voxel
/// of margin): distances and signs still from every triangle of
/// `geometry`, inside the box or not.
pub fn bake_over(
    scene: &Scene,
    geometry: &Geometry,
    rays: &RayCaster,
    bounds: (Vec3, Vec3),
    settings: Settings,
) -> Sdf {
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

/// The nearest triangle of a voxel's centre: (distance, triangle, point);
/// the triangle is [`NO_FACE`] where there is no single one.
type Nearest = (f32, u32, Vec3);

/// [`Nearest`]'s triangle beyond the narrow band, or where another
/// triangle is as near (within [`TIE`]): two coincident faces back to back
/// (a box resting on a floor, whose bottom face lies on the floor's) give
/// opposite signs there, so the voxel votes.
const NO_FACE: u32 = u32::MAX;
/// Squared distances within a factor 1 + `TIE` are a tie.
const TIE: f32 = 1e-3;

/// Step 1: the unsigned distance of every voxel's centre (clamped to
/// `band`), with its nearest triangle and point ([`NO_FACE`] beyond the
/// band or on a tie).
fn distances(grid: &Grid, rays: &RayCaster, band: Option<f32>) -> Vec<Nearest> {
    let max_d2 = band.map_or(f32::INFINITY, |b| b * b);
    (0..grid.len())
        .into_par_iter()
        .map(|i| {
            let p = grid.centre(i);
            match rays.closest_point_and_runner_up(p, max_d2, TIE) {
                None => (band.unwrap_or(f32::INFINITY), NO_FACE, p),
                Some((t, d, q, second)) => {
                    let tied = second * second <= d * d * (1.0 + TIE) + 1e-12;
                    (d, if tied { NO_FACE } else { t }, q)
                }
            }
        })
        .collect()
}

/// The sign the nearest point gives by itself, where it can: a nearest
/// point inside a one-sided triangle (not on its edges) is on the side of
/// `p` that the triangle's normal says, so `p` is inside where it lies
/// behind it (the pseudo-normal rule of Bærentzen & Aanæs 2005, on a
/// face). None on an edge or a vertex, on a double-sided face, where
/// another face is as near ([`NO_FACE`]), or right on the surface: those
/// vote.
fn face_sign(scene: &Scene, g: &Geometry, p: Vec3, (d, tri, q): Nearest) -> Option<bool> {
    if tri == NO_FACE || d <= 1e-6 {
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
            let mut cast = 0;
            match face_sign(scene, g, p, nearest[i]) {
                Some(true) => return (true, 0),
                // In front of the nearest face, and not enclosed over it.
                Some(false) => {
                    cast = 1;
                    if !meets_back(scene, g, rays, p, g.ng_ws[nearest[i].1 as usize]) {
                        return (false, cast);
                    }
                }
                None => {}
            }
            let (inside, total, votes_cast) = votes(scene, g, rays, p);
            (2 * inside > total, cast + votes_cast)
        })
        .collect();
    let cast = out.iter().map(|o| o.1).sum();
    (out.into_iter().map(|o| o.0).collect(), cast)
}

/// Whether the ray from `p` along `d` first meets the back of a one-sided
/// face: an *inside* vote ([`votes`]). Also the check on a voxel in front
/// of its nearest face ([`signs`]): along that face's normal it meets a
/// back face where it is enclosed over the face, as inside a solid with
/// no bottom face standing on a floor (the floor is nearest, seen from
/// its front, and alone would call the solid's lower part free space).
fn meets_back(scene: &Scene, g: &Geometry, rays: &RayCaster, p: Vec3, d: Vec3) -> bool {
    let Some(hit) = rays.closest_hit(p, d, f32::INFINITY) else {
        return false;
    };
    let tri = hit.tri as usize;
    g.ng_ws[tri].dot(d) > 0.0 && !scene.materials[g.material[tri] as usize].double_sided
}

/// The sign votes at `p`: (inside votes, votes, rays cast). [`VOTES`]
/// rays of a spherical Fibonacci set, and [`MORE_VOTES`] more where a
/// quarter to three quarters of the first ones said inside.
fn votes(scene: &Scene, g: &Geometry, rays: &RayCaster, p: Vec3) -> (u32, u32, u64) {
    let vote = |d: Vec3| meets_back(scene, g, rays, p, d);
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

    /// The preview's shader marches with the same constants as
    /// [`Sdf::march`], so its `sdf` view shows the surfaces the march finds.
    #[test]
    fn shader_march_constants_match() {
        let wgsl = include_str!("../../shaders/sdf.wgsl");
        let value = |name: &str| -> f64 {
            let line = wgsl
                .lines()
                .find(|l| l.starts_with(&format!("const {name}:")))
                .unwrap_or_else(|| panic!("shaders/sdf.wgsl has no {name}"));
            let v = line.split('=').nth(1).unwrap().trim().trim_end_matches(';');
            v.parse().unwrap_or_else(|_| panic!("{name} = {v}"))
        };
        let rust: [(&str, f64); 7] = [
            ("SDF_MARCH_STEPS", MARCH_STEPS as f64),
            ("SDF_MIN_STEP", MIN_STEP as f64),
            ("SDF_SURFACE_SLOPE", SURFACE_SLOPE as f64),
            ("SDF_NEAR", NEAR as f64),
            ("SDF_UNSIGNED", UNSIGNED as f64),
            ("SDF_UNSIGNED_FLAT", UNSIGNED_FLAT as f64),
            ("SDF_FLAT", FLAT as f64),
        ];
        for (name, v) in rust {
            let w = value(name);
            assert!(
                (w - v).abs() <= 1e-6 * v.abs(),
                "shaders/sdf.wgsl {name} = {w}, src/sdf/mod.rs has {v}"
            );
        }
    }

    #[test]
    fn grid_covers_the_bounds_with_a_margin() {
        let g = Grid::over((Vec3::ZERO, Vec3::new(1.0, 2.0, 0.5)), 0.25);
        assert_eq!(g.dims, [6, 10, 4]);
        assert_eq!(g.origin, Vec3::splat(-0.25));
        assert_eq!(g.xyz(6 * 10 + 6 + 1), [1, 1, 1]);
        assert!((g.centre(0) - Vec3::splat(-0.125)).length() < 1e-6);
    }

    /// A 16³ field of voxels of 1 m over [0, 16]³ holding `f` at the
    /// voxel centres.
    fn field(f: impl Fn(Vec3) -> f32) -> Sdf {
        let grid = Grid {
            origin: Vec3::ZERO,
            voxel: 1.0,
            dims: [16; 3],
        };
        let distance = (0..grid.len()).map(|i| f(grid.centre(i))).collect();
        Sdf {
            grid,
            distance,
            rays: 0,
        }
    }

    #[test]
    fn march_finds_a_solid_surface_at_its_zero_crossing() {
        // The solid x > 10.3 (a plane: trilinear interpolation is exact).
        let sdf = field(|p| 10.3 - p.x);
        let dir = Vec3::new(1.0, 0.3, -0.2).normalize();
        let o = Vec3::new(1.0, 6.0, 9.0);
        let t = sdf.march(o, dir, f32::INFINITY).unwrap();
        assert!(((o + dir * t).x - 10.3).abs() < 1e-3, "{}", (o + dir * t).x);
        // Short of it with tmax; from behind, where the field turns positive.
        assert_eq!(sdf.march(o, dir, 9.0), None);
        let back = sdf.march(Vec3::new(15.0, 6.0, 9.0), -Vec3::X, f32::INFINITY);
        assert!((back.unwrap() - 4.7).abs() < 1e-3, "{back:?}");
    }

    #[test]
    fn march_passes_surfaces_it_does_not_cross() {
        // A ray along the plane y = 3.0, 0.4 voxel above it (the old march
        // stopped within 0.6 voxel of any surface).
        let sdf = field(|p| p.y - 3.0);
        let o = Vec3::new(0.5, 3.4, 5.0);
        assert_eq!(sdf.march(o, Vec3::X, f32::INFINITY), None);
        // Past the edge of a box, 0.4 voxel off it.
        let cube = |p: Vec3| {
            let q = (p - Vec3::splat(8.0)).abs() - Vec3::splat(3.0);
            q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
        };
        let sdf = field(cube);
        let o = Vec3::new(0.5, 11.0 + 0.4 / 2f32.sqrt(), 11.0 + 0.4 / 2f32.sqrt());
        assert_eq!(sdf.march(o, Vec3::X, f32::INFINITY), None);
        // And into it, on its face.
        let t = sdf.march(Vec3::new(0.5, 8.2, 7.9), Vec3::X, f32::INFINITY);
        assert!((t.unwrap() - 4.5).abs() < 0.05, "{t:?}");
    }

    #[test]
    fn march_goes_through_a_sign_flip_in_open_air() {
        // Free space, 3 voxels from a surface at x = 0 (behind the ray),
        // with the sign flipped (wrongly) for x > 8: no surface there.
        let sdf = field(|p| if p.x > 8.0 { -p.x } else { p.x });
        let o = Vec3::new(4.0, 5.0, 5.0);
        assert_eq!(
            sdf.march(o, Vec3::new(1.0, 0.1, 0.0).normalize(), 30.0),
            None
        );
    }

    /// Open air (positive) round the solid layer behind a one-sided
    /// sphere's faces: a ray that runs past the layer's edge, where the
    /// field flips sign steeply and |field| dips under a quarter voxel
    /// without changing sign, meets no surface there.
    #[test]
    fn march_passes_the_edge_of_a_solid_layer() {
        let c = Vec3::splat(8.0);
        let sdf = field(|p| {
            // In front of the faces (r < 3) and in the layer behind them
            // (3 ≤ r ≤ 5): 3 − r; open air beyond: r − 3.
            let r = (p - c).length();
            if r <= 5.0 {
                3.0 - r
            } else {
                r - 3.0
            }
        });
        let o = Vec3::new(0.5, 8.0, 12.9);
        let dip = (0..=150)
            .map(|k| sdf.sample(o + Vec3::X * (k as f32 * 0.1)))
            .fold(f32::INFINITY, f32::min);
        assert!(dip > 0.0 && dip < UNSIGNED, "the ray dips to {dip}");
        assert_eq!(sdf.march(o, Vec3::X, 15.0), None);
    }

    #[test]
    fn march_hits_unsigned_sheets() {
        // A double-sided sheet (the field positive on both sides) at
        // x = s, from on a voxel centre's plane to midway between two:
        // found within a voxel (the agreement test's tolerance).
        for s in [6.5, 6.6, 6.75, 6.9, 7.0] {
            let sdf = field(|p| (p.x - s).abs());
            for dir in [Vec3::X, Vec3::new(1.0, 0.5, 0.2).normalize()] {
                let o = Vec3::new(1.0, 4.0, 4.0);
                let t = sdf.march(o, dir, f32::INFINITY);
                let want = (s - 1.0) / dir.x;
                assert!(
                    t.is_some_and(|t| (t - want).abs() < 1.0),
                    "sheet at {s}: {t:?}, {want}"
                );
            }
        }
    }
}
