//! Ray casting over every world triangle with an `obvhs` compressed wide
//! BVH (CWBVH, Ylitie et al. 2017; PLOC build, Meister & Bittner 2018).
//! Closest-hit and occlusion queries; alpha-masked materials are cut out
//! during traversal (any-hit test on the base colour alpha).

use crate::geometry::Geometry;
use crate::scene::{Alpha, Scene, Texture, TextureRef};
use glam::{Vec2, Vec3, Vec3A};
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use std::time::Duration;

/// A closest hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Global triangle id (index into [`Geometry`]).
    pub tri: u32,
    /// Distance along the (unit) direction.
    pub t: f32,
    /// Barycentric weight of corner 1.
    pub u: f32,
    /// Barycentric weight of corner 2.
    pub v: f32,
}

/// Triangle in the layout of Möller–Trumbore as arranged by madmann91's bvh
/// (e1 = v0 − v1, e2 = v2 − v0, n = e1 × e2): fewer operations per test.
#[derive(Clone, Copy, Debug)]
struct Tri {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
    n: Vec3A,
}

impl Tri {
    fn new(p: &[Vec3; 3]) -> Tri {
        let v0 = Vec3A::from(p[0]);
        let e1 = v0 - Vec3A::from(p[1]);
        let e2 = Vec3A::from(p[2]) - v0;
        Tri {
            v0,
            e1,
            e2,
            n: e1.cross(e2),
        }
    }

    /// (t, u, v) of the hit, with hit = (1−u−v)·p0 + u·p1 + v·p2, or None.
    #[inline(always)]
    fn intersect(&self, ray: &Ray) -> Option<(f32, f32, f32)> {
        let c = self.v0 - ray.origin;
        let r = ray.direction.cross(c);
        let det = self.n.dot(ray.direction);
        if det == 0.0 {
            return None;
        }
        let inv = 1.0 / det;
        let u = r.dot(self.e2) * inv;
        let v = r.dot(self.e1) * inv;
        if u < 0.0 || v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = self.n.dot(c) * inv;
        (t >= ray.tmin && t <= ray.tmax).then_some((t, u, v))
    }
}

/// One masked material's alpha: (texture slot in `Cutouts::textures` and
/// its transform), alpha factor, cutoff.
type AlphaMask = (Option<(usize, TextureRef)>, f32, f32);

/// Base colour alpha of the masked materials, for the any-hit test.
#[derive(Clone, Debug, Default)]
struct Cutouts {
    /// Per material, `None` when opaque.
    materials: Vec<Option<AlphaMask>>,
    textures: Vec<Texture>,
}

impl Cutouts {
    fn new(scene: &Scene) -> Cutouts {
        let mut c = Cutouts::default();
        for m in &scene.materials {
            c.materials.push(match m.alpha {
                Alpha::Opaque => None,
                Alpha::Mask { cutoff } => {
                    let tex = m.albedo_texture.as_ref().map(|r| {
                        c.textures.push(scene.textures[r.texture as usize].clone());
                        (c.textures.len() - 1, r.clone())
                    });
                    Some((tex, m.alpha_factor, cutoff))
                }
            });
        }
        c
    }

    fn is_cut(&self, material: u32, uv0: Vec2) -> bool {
        match &self.materials[material as usize] {
            None => false,
            Some((tex, factor, cutoff)) => {
                let a = match tex {
                    Some((slot, r)) => self.textures[*slot].sample(r.transform_uv(uv0)).w,
                    None => 1.0,
                };
                factor * a < *cutoff
            }
        }
    }
}

/// `geometry`'s world-space triangles as obvhs builds its BVHs from them
/// (the CPU's CWBVH here, the GPU's BVH2 in `gpu.rs`).
pub(crate) fn obvhs_triangles(geometry: &Geometry) -> Vec<Triangle> {
    geometry
        .p_ws
        .iter()
        .map(|p| Triangle {
            v0: p[0].into(),
            v1: p[1].into(),
            v2: p[2].into(),
        })
        .collect()
}

/// How far behind its origin every ray starts. obvhs's CWBVH box test
/// clamps a box's entry distance to at least 1e-4 (`cwbvh::node::EPSILON`,
/// an absolute distance), so a node left within 0.1 mm of the origin is
/// culled: a ray leaving a wall's foot into the floor it stands on went
/// through the corner (44 of 75,776 Cornell form-factor rays leaked). obvhs
/// traverses the ray started 0.2 mm back with `tmin` = 0.2 mm (the same
/// segment, every box exit past the clamp); triangles are tested against
/// the exact ray.
const BACK_OFF: f32 = 2e-4;

/// `dir` with −0.0 components made +0.0: obvhs picks the traversal octant
/// from the sign bits, and a −0.0 component (e.g. −(0, −1, 0) for a light
/// pointing straight down) made rays miss everything.
fn positive_zeros(dir: Vec3) -> Vec3 {
    dir + Vec3::ZERO
}

/// The scene's BVH and triangles, in BVH order.
pub struct RayCaster {
    bvh: CwBvh,
    tris: Vec<Tri>,
    /// BVH order → global triangle id.
    ids: Vec<u32>,
    /// BVH order → material, for masked triangles only (`u32::MAX` otherwise).
    masked_material: Vec<u32>,
    uv0: Vec<[Vec2; 3]>,
    cutouts: Cutouts,
}

impl RayCaster {
    /// Builds the BVH over `geometry` (obvhs medium build preset).
    pub fn new(scene: &Scene, geometry: &Geometry) -> RayCaster {
        Self::with_params(scene, geometry, BvhBuildParams::medium_build())
    }

    /// Builds the BVH over `geometry` with obvhs build settings `params`
    /// (for the benchmarks, which compare presets).
    pub fn with_params(scene: &Scene, geometry: &Geometry, params: BvhBuildParams) -> RayCaster {
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &obvhs_triangles(geometry),
            params,
            &mut Duration::default(),
        );
        let cutouts = Cutouts::new(scene);
        let ids: Vec<u32> = bvh.primitive_indices.clone();
        let ordered: Vec<Tri> = ids
            .iter()
            .map(|&g| Tri::new(&geometry.p_ws[g as usize]))
            .collect();
        let masked_material = ids
            .iter()
            .map(|&g| {
                let m = geometry.material[g as usize];
                if cutouts.materials[m as usize].is_some() {
                    m
                } else {
                    u32::MAX
                }
            })
            .collect();
        let uv0 = ids.iter().map(|&g| geometry.uv0[g as usize]).collect();
        RayCaster {
            bvh,
            tris: ordered,
            ids,
            masked_material,
            uv0,
            cutouts,
        }
    }

    #[inline(always)]
    fn test(&self, k: usize, ray: &Ray) -> Option<(f32, f32, f32)> {
        let (t, u, v) = self.tris[k].intersect(ray)?;
        let m = self.masked_material[k];
        if m != u32::MAX {
            let uv = self.uv0[k];
            let uv0 = uv[0] * (1.0 - u - v) + uv[1] * u + uv[2] * v;
            if self.cutouts.is_cut(m, uv0) {
                return None;
            }
        }
        Some((t, u, v))
    }

    /// The rays for `origin + t·dir`, `t ∈ [0, tmax]`: the one obvhs
    /// traverses, started [`BACK_OFF`] behind `origin` (so every node box on
    /// the segment is left after obvhs's box-entry clamp), and the exact one
    /// the triangles are tested against (so hit distances and barycentrics
    /// keep full precision; distances are handed to obvhs shifted by
    /// `BACK_OFF`, in its ray's terms).
    fn rays(origin: Vec3, dir: Vec3, tmax: f32) -> (Ray, Ray) {
        let dir = positive_zeros(dir);
        let traversed = Ray::new(
            (origin - BACK_OFF * dir).into(),
            dir.into(),
            BACK_OFF,
            tmax + BACK_OFF,
        );
        let exact = Ray {
            origin: origin.into(),
            tmin: 0.0,
            tmax,
            ..traversed
        };
        (traversed, exact)
    }

    /// The closest hit along `origin + t·dir`, `t ∈ [0, tmax]` (`dir` unit).
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        let (ray, exact) = Self::rays(origin, dir, tmax);
        let mut hit = obvhs::ray::RayHit::none();
        let mut best = (0.0f32, 0.0f32, 0.0f32);
        let found = self
            .bvh
            .ray_traverse(ray, &mut hit, |r, k| match self.test(k, &exact) {
                Some((t, u, v)) => {
                    let shifted = t + BACK_OFF;
                    if shifted < r.tmax {
                        best = (t, u, v);
                    }
                    shifted
                }
                None => f32::INFINITY,
            });
        found.then(|| Hit {
            tri: self.ids[hit.primitive_id as usize],
            t: best.0,
            u: best.1,
            v: best.2,
        })
    }

    /// True when nothing lies along `origin + t·dir` for `t ∈ [0, tmax]`.
    pub fn unoccluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let (ray, exact) = Self::rays(origin, dir, tmax);
        self.bvh.ray_traverse_miss(ray, |_, k| {
            self.test(k, &exact)
                .map_or(f32::INFINITY, |h| h.0 + BACK_OFF)
        })
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// True when there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Stream;

    fn random_geometry(n: usize, seed: u64) -> Geometry {
        let mut s = Stream::new(seed, 0, 0);
        let mut g = Geometry::default();
        for _ in 0..n {
            let c = Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 10.0;
            let p =
                [0, 1, 2].map(|_| c + Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) - 0.5);
            g.instance.push(0);
            g.p_ws.push(p);
            g.n_ws.push([Vec3::Z; 3]);
            g.ng_ws.push(Vec3::Z);
            g.area.push(1.0);
            g.uv0.push([Vec2::ZERO; 3]);
            g.uv_lm.push([Vec2::ZERO; 3]);
            g.page.push(0);
            g.chart.push(0);
            g.material.push(0);
        }
        g
    }

    /// A direction with a −0.0 component still finds its hit (regression:
    /// a sun pointing straight down cast no shadows).
    #[test]
    fn negative_zero_directions_hit() {
        let scene = Scene {
            materials: vec![crate::scene::Material::fallback()],
            ..Default::default()
        };
        let mut g = random_geometry(1, 0);
        g.p_ws[0] = [
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, -1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let rc = RayCaster::new(&scene, &g);
        for d in [
            Vec3::new(-0.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, -0.0),
            Vec3::new(-0.0, 1.0, -0.0),
        ] {
            assert!(
                rc.closest_hit(Vec3::ZERO, d, f32::INFINITY).is_some(),
                "{d:?}"
            );
            assert!(!rc.unoccluded(Vec3::ZERO, d, f32::INFINITY), "{d:?}");
        }
    }

    /// BVH closest hits equal a brute-force scan of every triangle.
    #[test]
    fn bvh_matches_brute_force() {
        let scene = Scene {
            materials: vec![crate::scene::Material::fallback()],
            ..Default::default()
        };
        let g = random_geometry(2000, 3);
        let rc = RayCaster::new(&scene, &g);
        let brute: Vec<Tri> = g.p_ws.iter().map(Tri::new).collect();
        let mut s = Stream::new(9, 0, 0);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 12.0 - 1.0;
            let d = (Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) - 0.5).normalize();
            let ray = Ray::new(o.into(), d.into(), 0.0, f32::INFINITY);
            let mut best: Option<(f32, u32, f32, f32)> = None;
            for (i, t) in brute.iter().enumerate() {
                if let Some((tt, u, v)) = t.intersect(&ray) {
                    if best.is_none_or(|b| tt < b.0) {
                        best = Some((tt, i as u32, u, v));
                    }
                }
            }
            let got = rc.closest_hit(o, d, f32::INFINITY);
            match (best, got) {
                (None, None) => {}
                (Some(b), Some(h)) => {
                    hits += 1;
                    assert_eq!(b.1, h.tri);
                    assert!((b.0 - h.t).abs() < 1e-4);
                    // Barycentrics reconstruct the hit point.
                    let p = g.point(h.tri, h.u, h.v);
                    assert!((p - (o + d * h.t)).length() < 1e-3);
                }
                (b, h) => panic!("brute force {b:?}, bvh {h:?}"),
            }
            assert_eq!(rc.unoccluded(o, d, f32::INFINITY), best.is_none());
        }
        assert!(hits > 200, "too few hits ({hits}) to mean anything");
    }

    /// A ray leaving a wall's bottom edge into the floor it stands on hits
    /// the floor (Cornell box back-wall/floor corner; regression).
    #[test]
    fn corner_rays_hit_the_floor() {
        let scene = Scene {
            materials: vec![crate::scene::Material::fallback()],
            ..Default::default()
        };
        let mut g = random_geometry(2, 0);
        g.p_ws[0] = [
            Vec3::new(0.5528, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.5592),
            Vec3::new(0.5496, 0.0, 0.5592),
        ];
        g.p_ws[1] = [
            Vec3::new(0.5528, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.5592),
        ];
        let rc = RayCaster::new(&scene, &g);
        let o = Vec3::new(0.1108172, 0.000053278272, 0.55918473);
        let d = Vec3::new(0.15438633, -0.63962615, -0.75302273).normalize();
        let h = rc
            .closest_hit(o, d, f32::INFINITY)
            .expect("the corner ray leaks");
        assert_eq!(h.tri, 0);
        assert!((h.t - 8.33e-5).abs() < 1e-6, "t = {}", h.t);
        assert!(!rc.unoccluded(o, d, 1.0));
        // The segment still ends where asked.
        assert!(rc.closest_hit(o, d, 8e-5).is_none());
        assert!(rc.unoccluded(o, d, 8e-5));
    }
}
