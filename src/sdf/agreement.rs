//! Sphere tracing against ray casting (issue #24): random rays marched
//! through a field ([`Sdf::march`]) and cast on the BVH
//! ([`RayCaster::closest_hit`]); a ray agrees where both miss or both hit
//! within one voxel of each other along it. A ray that does not agree is
//! put in a [`Class`] by what lies where the two parted, so that the
//! remainder can be reported by cause. Used by `tests/sdf.rs` and
//! `tools/sdf_agreement.rs`.

use super::Sdf;
use crate::layout::geometry::Geometry;
use crate::raycast::RayCaster;
use crate::scene::{Alpha, Scene};
use crate::util::sampling::{cosine_hemisphere, to_world, Stream};
use glam::Vec3;

/// Why a marched ray and the BVH's disagree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Class {
    /// The march stopped at a surface the ray passes within a voxel of but
    /// does not cross (an edge, a corner, a wall it runs along).
    Grazing,
    /// The march stopped on an alpha-masked triangle where the BVH's ray
    /// went through its cut-out (the field counts masked triangles whole).
    CutOut,
    /// The march stopped more than a voxel from any surface: a sign flip in
    /// open air (the field negative where no solid is).
    OpenAir,
    /// The ray meets its surface at under 11.5° (|cos| < 0.2): the march
    /// found it, but a fraction of a voxel across it is voxels along it.
    GrazingIncidence,
    /// The ray meets a double-sided material's face, whose field is
    /// unsigned (positive on both sides), and the march went past it.
    DoubleSided,
    /// The field has no zero crossing where the ray meets its surface (a
    /// sheet or a solid thinner than a voxel), and the march hit the next
    /// surface, under two voxels behind: closer than a voxel or two, the
    /// two are one surface at the field's resolution.
    Merged,
    /// The field has no zero crossing where the ray meets its surface, and
    /// the march went past it.
    NoCrossing,
    /// The BVH's hit lies within a voxel of the grid's border.
    Border,
    /// None of the above.
    Other,
}

impl Class {
    /// Every class, in report order.
    pub const ALL: [Class; 9] = [
        Class::Grazing,
        Class::CutOut,
        Class::OpenAir,
        Class::GrazingIncidence,
        Class::DoubleSided,
        Class::Merged,
        Class::NoCrossing,
        Class::Border,
        Class::Other,
    ];

    /// A short description for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Class::Grazing => "stopped by a surface the ray passes but does not cross",
            Class::CutOut => "stopped on an alpha cut-out the ray goes through",
            Class::OpenAir => "stopped in open air (a sign flip)",
            Class::GrazingIncidence => "hit at under 11.5° (|cos| < 0.2), off by over a voxel",
            Class::DoubleSided => "went through a double-sided (unsigned) face",
            Class::Merged => "hit under 2 voxels behind a surface with no zero crossing",
            Class::NoCrossing => "went through a surface with no zero crossing (thin)",
            Class::Border => "hit within a voxel of the grid's border",
            Class::Other => "other",
        }
    }
}

/// One ray's outcome: None where the march agrees with the BVH, else the
/// class of the disagreement, with the march's hit (or miss) and the
/// BVH's.
#[derive(Clone, Copy, Debug)]
pub struct Outcome {
    /// The march's hit distance.
    pub marched: Option<f32>,
    /// The BVH's hit distance.
    pub cast: Option<f32>,
    /// None where they agree.
    pub class: Option<Class>,
    /// The march stopped more than a voxel short of the BVH's hit (or
    /// where the BVH saw nothing).
    pub early: bool,
}

/// Marches and casts `origin + t·dir` (unit `dir`) and classifies the
/// outcome (see [`Class`]).
pub fn compare(
    scene: &Scene,
    g: &Geometry,
    rays: &RayCaster,
    sdf: &Sdf,
    origin: Vec3,
    dir: Vec3,
) -> Outcome {
    let voxel = sdf.grid.voxel;
    let hit = rays.closest_hit(origin, dir, f32::INFINITY);
    let marched = sdf.march(origin, dir, f32::INFINITY);
    let cast = hit.map(|h| h.t);
    let agree = match (cast, marched) {
        (None, None) => true,
        (Some(a), Some(b)) => (a - b).abs() <= voxel,
        _ => false,
    };
    let early = match (cast, marched) {
        (_, None) => false,
        (None, Some(_)) => true,
        (Some(a), Some(b)) => b < a - voxel,
    };
    let class = (!agree).then(|| {
        if early {
            stopped_short(scene, g, rays, sdf, origin + dir * marched.unwrap_or(0.0))
        } else {
            let hit = hit.expect("a hit the march missed");
            went_past(scene, g, sdf, (origin, dir), hit, marched)
        }
    });
    Outcome {
        marched,
        cast,
        class,
        early,
    }
}

/// Why the march stopped at `p`, short of the BVH's hit.
fn stopped_short(scene: &Scene, g: &Geometry, rays: &RayCaster, sdf: &Sdf, p: Vec3) -> Class {
    let voxel = sdf.grid.voxel;
    match rays.closest_point(p, (1.5 * voxel).powi(2)) {
        None => Class::OpenAir,
        Some((tri, _, _)) => {
            let m = &scene.materials[g.material[tri as usize] as usize];
            if matches!(m.alpha, Alpha::Mask { .. }) {
                Class::CutOut
            } else {
                Class::Grazing
            }
        }
    }
}

/// Why the march went past (or missed) the BVH's hit `hit`.
fn went_past(
    scene: &Scene,
    g: &Geometry,
    sdf: &Sdf,
    (origin, dir): (Vec3, Vec3),
    hit: crate::raycast::Hit,
    marched: Option<f32>,
) -> Class {
    let voxel = sdf.grid.voxel;
    let tri = hit.tri as usize;
    let q = origin + dir * hit.t;
    let gr = &sdf.grid;
    let size = Vec3::new(gr.dims[0] as f32, gr.dims[1] as f32, gr.dims[2] as f32) * voxel;
    let inset = (q - gr.origin).min(gr.origin + size - q).min_element();
    if g.ng_ws[tri].dot(dir).abs() < 0.2 {
        Class::GrazingIncidence
    } else if scene.materials[g.material[tri] as usize].double_sided {
        Class::DoubleSided
    } else if inset < voxel {
        Class::Border
    } else if sdf.sample(q + dir * (0.5 * voxel)) > 0.0 && sdf.sample(q - dir * (0.5 * voxel)) > 0.0
    {
        if marched.is_some_and(|t| t < hit.t + 2.0 * voxel) {
            Class::Merged
        } else {
            Class::NoCrossing
        }
    } else {
        Class::Other
    }
}

/// `n` rays from random points of `bounds` in open air (the field at
/// least two voxels there), in directions cosine-distributed about +Y or
/// −Y (even odds): the rays of the agreement test. Deterministic for
/// `seed`.
pub fn random_rays(sdf: &Sdf, bounds: (Vec3, Vec3), seed: u64, n: usize) -> Vec<(Vec3, Vec3)> {
    let mut rng = Stream::new(seed, crate::util::sampling::purpose::SDF_AGREEMENT, 0);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let o = bounds.0 + (bounds.1 - bounds.0) * u;
        if sdf.sample(o) < 2.0 * sdf.grid.voxel {
            continue;
        }
        // (The hemisphere's sample is drawn before the axis's.)
        let local = cosine_hemisphere(rng.next_vec2());
        let axis = if rng.next_f32() < 0.5 {
            Vec3::Y
        } else {
            Vec3::NEG_Y
        };
        let d = to_world(local, axis);
        out.push((o, d));
    }
    out
}
