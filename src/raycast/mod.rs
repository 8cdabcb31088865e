//! Ray casting over every world triangle: obvhs builds a binary BVH (PLOC,
//! Meister & Bittner 2018), collapsed into our 4- or 8-wide SIMD BVH
//! ([`bvh`]; 8 wide with AVX2).
//! Closest-hit and occlusion queries; alpha-masked materials are cut out
//! during traversal (any-hit test on the base colour alpha).

pub mod batch;
mod bvh;
pub mod device;
#[cfg(feature = "gpu")]
pub mod gpu;

pub use bvh::BvhStats;

use crate::layout::geometry::Geometry;
use crate::scene::{Alpha, Scene, Texture, TextureRef};
use bvh::Bvh4;
#[cfg(target_arch = "x86_64")]
use bvh::Bvh8;
use glam::{Vec2, Vec3};
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
/// (the CPU's BVH4 here, the GPU's BVH2 in `gpu.rs`).
pub(crate) fn obvhs_triangles(geometry: &Geometry, casters: Option<&[u32]>) -> Vec<Triangle> {
    let tri = |p: &[Vec3; 3]| Triangle {
        v0: p[0].into(),
        v1: p[1].into(),
        v2: p[2].into(),
    };
    match casters {
        Some(ids) => ids
            .iter()
            .map(|&g| tri(&geometry.p_ws[g as usize]))
            .collect(),
        None => geometry.p_ws.iter().map(tri).collect(),
    }
}

/// The triangles rays can meet: those of instances that cast shadows
/// (`extras.radbake.cast_shadows`, [`crate::scene::Instance`]); `None`
/// where every instance does (the BVH then indexes `geometry` directly).
pub fn shadow_casters(scene: &Scene, geometry: &Geometry) -> Option<Vec<u32>> {
    let casts = |i: u32| {
        scene
            .instances
            .get(i as usize)
            .is_none_or(|inst| inst.cast_shadows)
    };
    if geometry.instance.iter().all(|&i| casts(i)) {
        return None;
    }
    Some(
        (0..geometry.len() as u32)
            .filter(|&t| casts(geometry.instance[t as usize]))
            .collect(),
    )
}

/// Most triangles in a leaf of obvhs's binary BVH before the BVH4's
/// cost-minimal collapse, which merges subtrees into leaves itself.
const BVH2_LEAF: u32 = 4;

/// How wide the CPU ray caster's BVH is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BvhWidth {
    /// 8 where the CPU has AVX2, else 4.
    #[default]
    Auto,
    /// 4 children per node (SSE, NEON).
    Four,
    /// 8 children per node (AVX2; 4 where the CPU lacks it).
    Eight,
}

/// True when this CPU runs the 8-wide BVH's AVX2 code.
fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The BVH, 4 or 8 wide (the same hits either way).
enum Accel {
    Four(Bvh4),
    #[cfg(target_arch = "x86_64")]
    Eight(Bvh8),
}

/// The scene's BVH and triangles, in BVH order.
pub struct RayCaster {
    /// The triangles in the BVH where not all are ([`shadow_casters`]).
    casters: Option<Vec<u32>>,
    bvh: Accel,
    /// BVH order → global triangle id.
    ids: Vec<u32>,
    /// BVH order → material, for masked triangles only (`u32::MAX` otherwise).
    masked_material: Vec<u32>,
    uv0: Vec<[Vec2; 3]>,
    cutouts: Cutouts,
}

impl RayCaster {
    /// Builds the BVH over `geometry` (obvhs medium build preset; 8 wide
    /// where the CPU has AVX2, else 4).
    pub fn new(scene: &Scene, geometry: &Geometry) -> RayCaster {
        Self::with_params(scene, geometry, BvhBuildParams::medium_build())
    }

    /// Builds the BVH over `geometry` with obvhs build settings `params`
    /// (for the benchmarks, which compare presets); obvhs's leaves are
    /// capped at [`BVH2_LEAF`] triangles, and the BVH4's collapse decides
    /// its own leaves.
    pub fn with_params(scene: &Scene, geometry: &Geometry, params: BvhBuildParams) -> RayCaster {
        Self::with_width(scene, geometry, params, BvhWidth::Auto)
    }

    /// [`RayCaster::with_params`] with the BVH's width chosen.
    pub fn with_width(
        scene: &Scene,
        geometry: &Geometry,
        params: BvhBuildParams,
        width: BvhWidth,
    ) -> RayCaster {
        let params = BvhBuildParams {
            max_prims_per_leaf: params.max_prims_per_leaf.min(BVH2_LEAF),
            ..params
        };
        let casters = shadow_casters(scene, geometry);
        let bvh2 = obvhs::bvh2::builder::build_bvh2_from_tris(
            &obvhs_triangles(geometry, casters.as_deref()),
            params,
            &mut Duration::default(),
        );
        let cutouts = Cutouts::new(scene);
        let ids: Vec<u32> = match &casters {
            Some(c) => bvh2
                .primitive_indices
                .iter()
                .map(|&i| c[i as usize])
                .collect(),
            None => bvh2.primitive_indices.clone(),
        };
        let ordered: Vec<[Vec3; 3]> = ids.iter().map(|&g| geometry.p_ws[g as usize]).collect();
        let masked_material: Vec<u32> = ids
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
        let masked: Vec<bool> = masked_material.iter().map(|&m| m != u32::MAX).collect();
        // Eight wide only where this CPU runs its AVX2 code.
        let eight = width != BvhWidth::Four && avx2();
        let bvh = match eight {
            #[cfg(target_arch = "x86_64")]
            true => Accel::Eight(Bvh8::new(&bvh2, &ordered, &masked)),
            _ => Accel::Four(Bvh4::new(&bvh2, &ordered, &masked)),
        };
        let uv0 = ids.iter().map(|&g| geometry.uv0[g as usize]).collect();
        RayCaster {
            casters,
            bvh,
            ids,
            masked_material,
            uv0,
            cutouts,
        }
    }

    /// The triangles in the BVH, where not every triangle is
    /// ([`shadow_casters`]).
    pub fn casters(&self) -> Option<&[u32]> {
        self.casters.as_deref()
    }

    /// False where BVH-order triangle `k` is cut out (alpha mask) at
    /// barycentrics (u, v); the BVH asks only for masked triangles.
    #[inline(always)]
    fn keep(&self, k: u32, u: f32, v: f32) -> bool {
        let m = self.masked_material[k as usize];
        if m == u32::MAX {
            return true;
        }
        let uv = self.uv0[k as usize];
        !self
            .cutouts
            .is_cut(m, uv[0] * (1.0 - u - v) + uv[1] * u + uv[2] * v)
    }

    /// The closest hit along `origin + t·dir`, `t ∈ [0, tmax]` (`dir` unit).
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        let keep = |k, u, v| self.keep(k, u, v);
        match &self.bvh {
            Accel::Four(b) => b.closest_hit(origin, dir, tmax, keep),
            // SAFETY: `Eight` is built only where AVX2 was detected.
            #[cfg(target_arch = "x86_64")]
            Accel::Eight(b) => unsafe { b.closest_hit_avx2(origin, dir, tmax, keep) },
        }
        .map(|(k, t, u, v)| Hit {
            tri: self.ids[k as usize],
            t,
            u,
            v,
        })
    }

    /// True when nothing lies along `origin + t·dir` for `t ∈ [0, tmax]`.
    pub fn unoccluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let keep = |k, u, v| self.keep(k, u, v);
        match &self.bvh {
            Accel::Four(b) => b.unoccluded(origin, dir, tmax, keep),
            // SAFETY: as in `closest_hit`.
            #[cfg(target_arch = "x86_64")]
            Accel::Eight(b) => unsafe { b.unoccluded_avx2(origin, dir, tmax, keep) },
        }
    }

    /// The triangle nearest to `p` within √`max_dist2`: (global triangle id,
    /// distance, nearest point). One best-first traversal of the BVH (see
    /// `bvh::Bvh::closest_point`); alpha cut-outs are not consulted.
    pub fn closest_point(&self, p: Vec3, max_dist2: f32) -> Option<(u32, f32, Vec3)> {
        self.closest_point_and_runner_up(p, max_dist2, 0.0)
            .map(|(t, d, q, _)| (t, d, q))
    }

    /// [`Self::closest_point`] and the distance of the runner-up, the
    /// nearest other triangle: exact where it is within a factor
    /// √(1 + `tie`) of the nearest, else larger. A runner-up at the same
    /// distance is a tie (a coincident face, an edge, the medial axis).
    pub fn closest_point_and_runner_up(
        &self,
        p: Vec3,
        max_dist2: f32,
        tie: f32,
    ) -> Option<(u32, f32, Vec3, f32)> {
        match &self.bvh {
            Accel::Four(b) => b.closest_point(p, max_dist2, tie),
            #[cfg(target_arch = "x86_64")]
            Accel::Eight(b) => b.closest_point(p, max_dist2, tie),
        }
        .map(|(k, d2, q, second)| (self.ids[k as usize], d2.sqrt(), q, second.sqrt()))
    }

    /// Children per BVH node: 4 or 8.
    pub fn width(&self) -> usize {
        match &self.bvh {
            Accel::Four(_) => 4,
            #[cfg(target_arch = "x86_64")]
            Accel::Eight(_) => 8,
        }
    }

    /// The BVH's shape and surface-area cost.
    pub fn stats(&self) -> BvhStats {
        match &self.bvh {
            Accel::Four(b) => b.stats(),
            #[cfg(target_arch = "x86_64")]
            Accel::Eight(b) => b.stats(),
        }
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// True when there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::sampling::Stream;

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

    /// A ray caster over exactly these opaque triangles.
    fn caster(triangles: &[[Vec3; 3]]) -> RayCaster {
        let scene = Scene {
            materials: vec![crate::scene::Material::fallback()],
            ..Default::default()
        };
        let mut g = random_geometry(triangles.len(), 0);
        g.p_ws.copy_from_slice(triangles);
        RayCaster::new(&scene, &g)
    }

    /// Alpha-masked triangles cut out by their alpha are passed through, by
    /// closest-hit and occlusion rays alike, while opaque and kept masked
    /// ones in the same packet still hit (the packet's masked-lane flags).
    #[test]
    fn cut_out_triangles_let_rays_through() {
        use crate::scene::{Alpha, Material};
        let masked = |alpha| Material {
            alpha: Alpha::Mask { cutoff: 0.5 },
            alpha_factor: alpha,
            ..Material::fallback()
        };
        let scene = Scene {
            materials: vec![Material::fallback(), masked(0.2), masked(0.9)],
            ..Default::default()
        };
        // Three parallel squares (two triangles each) across the +z axis at
        // z = 1 (cut out), 2 (masked but kept) and 3 (opaque).
        let mut g = random_geometry(6, 0);
        for (k, (z, m)) in [(1.0, 1), (2.0, 2), (3.0, 0)].into_iter().enumerate() {
            let c = |x: f32, y: f32| Vec3::new(x, y, z);
            g.p_ws[2 * k] = [c(-1.0, -1.0), c(1.0, -1.0), c(1.0, 1.0)];
            g.p_ws[2 * k + 1] = [c(-1.0, -1.0), c(1.0, 1.0), c(-1.0, 1.0)];
            g.material[2 * k] = m;
            g.material[2 * k + 1] = m;
        }
        let rc = RayCaster::new(&scene, &g);
        let o = Vec3::new(0.3, -0.2, 0.0);
        let h = rc.closest_hit(o, Vec3::Z, f32::INFINITY).expect("a hit");
        assert!((h.t - 2.0).abs() < 1e-5, "t = {}", h.t);
        assert_eq!(g.material[h.tri as usize], 2);
        // Only the cut-out square lies within 1.5.
        assert!(rc.unoccluded(o, Vec3::Z, 1.5));
        assert!(!rc.unoccluded(o, Vec3::Z, 2.5));
        // With the kept square cut out too, the opaque one is next.
        let scene = Scene {
            materials: vec![Material::fallback(), masked(0.2), masked(0.3)],
            ..Default::default()
        };
        let rc = RayCaster::new(&scene, &g);
        let h = rc.closest_hit(o, Vec3::Z, f32::INFINITY).expect("a hit");
        assert!((h.t - 3.0).abs() < 1e-5, "t = {}", h.t);
        assert!(rc.unoccluded(o, Vec3::Z, 2.5));
        assert!(!rc.unoccluded(o, Vec3::Z, 3.5));
    }

    /// A direction with a −0.0 component still finds its hit (regression:
    /// a sun pointing straight down cast no shadows).
    #[test]
    fn negative_zero_directions_hit() {
        let rc = caster(&[[
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, -1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ]]);
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
        for width in [BvhWidth::Four, BvhWidth::Eight] {
            let rc = RayCaster::with_width(&scene, &g, BvhBuildParams::medium_build(), width);
            brute_force_agrees(&rc, &g);
        }
    }

    /// `rc`'s closest hits and occlusion equal a brute-force scan of every
    /// triangle of `g`.
    fn brute_force_agrees(rc: &RayCaster, g: &Geometry) {
        // Textbook Möller–Trumbore, independent of the SIMD kernel's form.
        let brute = |p: &[Vec3; 3], o: Vec3, d: Vec3| -> Option<(f32, f32, f32)> {
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            let h = d.cross(e2);
            let a = e1.dot(h);
            if a.abs() < 1e-12 {
                return None;
            }
            let s = o - p[0];
            let u = s.dot(h) / a;
            let q = s.cross(e1);
            let v = d.dot(q) / a;
            let t = e2.dot(q) / a;
            (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= 0.0).then_some((t, u, v))
        };
        let mut s = Stream::new(9, 0, 0);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 12.0 - 1.0;
            let d = (Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) - 0.5).normalize();
            let mut best: Option<(f32, u32, f32, f32)> = None;
            for (i, p) in g.p_ws.iter().enumerate() {
                if let Some((tt, u, v)) = brute(p, o, d) {
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
                    assert!((b.2 - h.u).abs() < 1e-3 && (b.3 - h.v).abs() < 1e-3);
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

    /// The 4- and 8-wide BVHs give the same answers, bit for bit, also
    /// where coplanar twins (the same triangle again) tie at one distance.
    #[test]
    fn widths_give_the_same_hits() {
        let scene = Scene {
            materials: vec![crate::scene::Material::fallback()],
            ..Default::default()
        };
        // Eight copies of each triangle: more than a packet holds, so twins
        // lie in different leaves, visited in different orders.
        let mut g = random_geometry(6000, 4);
        for k in 0..6000 {
            g.p_ws[k] = g.p_ws[k & !7];
        }
        let p = BvhBuildParams::medium_build();
        let four = RayCaster::with_width(&scene, &g, p, BvhWidth::Four);
        let eight = RayCaster::with_width(&scene, &g, p, BvhWidth::Eight);
        assert_eq!(four.width(), 4);
        let mut s = Stream::new(2, 0, 0);
        let mut hits = 0;
        for _ in 0..3000 {
            let o = Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 12.0 - 1.0;
            let d = (Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) - 0.5).normalize();
            let tmax = s.next_f32() * 10.0;
            let a = four.closest_hit(o, d, f32::INFINITY);
            let b = eight.closest_hit(o, d, f32::INFINITY);
            assert_eq!(
                a.map(|h| (h.tri, h.t.to_bits(), h.u.to_bits(), h.v.to_bits())),
                b.map(|h| (h.tri, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
            );
            // Of two twins the one first in BVH order wins, however the
            // BVH is visited.
            if let Some(h) = a {
                let at = |tri: u32| four.ids.iter().position(|&g| g == tri).unwrap();
                let first = (h.tri & !7..(h.tri & !7) + 8).map(at).min().unwrap();
                assert_eq!(at(h.tri), first, "a later twin ({}) won", h.tri);
                hits += 1;
            }
            assert_eq!(four.unoccluded(o, d, tmax), eight.unoccluded(o, d, tmax));
        }
        assert!(hits > 300, "too few hits ({hits})");
    }

    /// A ray leaving a wall's bottom edge into the floor it stands on hits
    /// the floor (Cornell box back-wall/floor corner; regression).
    #[test]
    fn corner_rays_hit_the_floor() {
        let rc = caster(&[
            [
                Vec3::new(0.5528, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 0.5592),
                Vec3::new(0.5496, 0.0, 0.5592),
            ],
            [
                Vec3::new(0.5528, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 0.5592),
            ],
        ]);
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
