//! World-space triangles: every instance's triangles flattened through its
//! transform, with their lightmap coordinates from the atlas. Shared by the
//! texel rasteriser, the ray caster and every stage that turns a ray hit into
//! a lightmap texel.

use crate::layout::atlas::Atlas;
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Flattened world-space triangles (struct of arrays, indexed by a global
/// triangle id).
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    /// Instance of each triangle.
    pub instance: Vec<u32>,
    /// Corner positions (world), counter-clockwise from the front.
    pub p_ws: Vec<[Vec3; 3]>,
    /// Corner shading normals (world, unit).
    pub n_ws: Vec<[Vec3; 3]>,
    /// Unit geometric normal (front side).
    pub ng_ws: Vec<Vec3>,
    /// World area (m²).
    pub area: Vec<f32>,
    /// Corner `TEXCOORD_0`.
    pub uv0: Vec<[Vec2; 3]>,
    /// Corner lightmap coordinates in atlas texels (not normalised).
    pub uv_lm: Vec<[Vec2; 3]>,
    /// Atlas page.
    pub page: Vec<u32>,
    /// Chart (unique per mesh; combine with `instance` for a global chart).
    pub chart: Vec<u32>,
    /// Material.
    pub material: Vec<u32>,
}

impl Geometry {
    /// Flattens `scene` with the lightmap coordinates of `atlas`.
    pub fn new(scene: &Scene, atlas: &Atlas) -> Geometry {
        Geometry::build(scene, Some(atlas))
    }

    /// Flattens `scene` without lightmap coordinates (all zero, page 0,
    /// chart 0): for consumers that only trace rays, such as the reference
    /// path tracer.
    pub fn unmapped(scene: &Scene) -> Geometry {
        Geometry::build(scene, None)
    }

    fn build(scene: &Scene, atlas: Option<&Atlas>) -> Geometry {
        let per_instance: Vec<Geometry> = scene
            .instances
            .par_iter()
            .enumerate()
            .map(|(i, inst)| {
                let mesh = &scene.meshes[inst.mesh as usize];
                let unwrap = atlas.map(|a| (&a.meshes[inst.mesh as usize], a.instances[i], a));
                let m = inst.world_from_local;
                let nm = inst.normal_matrix();
                let flip = inst.mirrors();
                let mut g = Geometry::default();
                for (t, &src) in mesh.triangles.iter().enumerate() {
                    let mut order = [0usize, 1, 2];
                    if flip {
                        order.swap(1, 2);
                    }
                    let p = order.map(|k| m.transform_point3(mesh.positions[src[k] as usize]));
                    let n =
                        order.map(|k| (nm * mesh.normals[src[k] as usize]).normalize_or(Vec3::Y));
                    let uv0 = order.map(|k| mesh.uv0[src[k] as usize]);
                    let (lm, page, chart) = match unwrap {
                        Some((u, rect, a)) => {
                            let out_tri = u.triangles[t];
                            (
                                order.map(|k| {
                                    rect.to_texels(u.uv[out_tri[k] as usize], a.width, a.height)
                                }),
                                rect.page,
                                u.chart[out_tri[0] as usize],
                            )
                        }
                        None => ([Vec2::ZERO; 3], 0, 0),
                    };
                    let cross = (p[1] - p[0]).cross(p[2] - p[0]);
                    g.instance.push(i as u32);
                    g.p_ws.push(p);
                    g.n_ws.push(n);
                    g.ng_ws.push(cross.normalize_or(n[0]));
                    g.area.push(0.5 * cross.length());
                    g.uv0.push(uv0);
                    g.uv_lm.push(lm);
                    g.page.push(page);
                    g.chart.push(chart);
                    g.material.push(mesh.triangle_material[t]);
                }
                g
            })
            .collect();
        let mut all = Geometry::default();
        for g in per_instance {
            all.instance.extend(g.instance);
            all.p_ws.extend(g.p_ws);
            all.n_ws.extend(g.n_ws);
            all.ng_ws.extend(g.ng_ws);
            all.area.extend(g.area);
            all.uv0.extend(g.uv0);
            all.uv_lm.extend(g.uv_lm);
            all.page.extend(g.page);
            all.chart.extend(g.chart);
            all.material.extend(g.material);
        }
        all
    }

    /// World bounds (min, max) of every triangle; None without triangles.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let (lo, hi) = self.p_ws.iter().flatten().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.instance.len()
    }

    /// True when there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.instance.is_empty()
    }

    /// Barycentric interpolation helpers: weights (1−u−v, u, v).
    pub fn point(&self, tri: u32, u: f32, v: f32) -> Vec3 {
        let p = &self.p_ws[tri as usize];
        p[0] * (1.0 - u - v) + p[1] * u + p[2] * v
    }

    /// Barycentrics (u, v) (the weights of corners 1 and 2) of point `q`
    /// in triangle `tri`'s plane: each corner's share is the signed area of
    /// the sub-triangle opposite it. (0, 0) for a degenerate triangle.
    pub fn barycentrics(&self, tri: u32, q: Vec3) -> (f32, f32) {
        let [a, b, c] = self.p_ws[tri as usize];
        let n = (b - a).cross(c - a);
        let area2 = n.length_squared();
        if area2 <= 0.0 {
            return (0.0, 0.0);
        }
        let u = (c - q).cross(a - q).dot(n) / area2;
        let v = (a - q).cross(b - q).dot(n) / area2;
        (u, v)
    }

    /// `TEXCOORD_0` at barycentrics (u, v).
    pub fn uv0_at(&self, tri: u32, u: f32, v: f32) -> Vec2 {
        let t = &self.uv0[tri as usize];
        t[0] * (1.0 - u - v) + t[1] * u + t[2] * v
    }

    /// Lightmap texel coordinate at barycentrics (u, v).
    pub fn uv_lm_at(&self, tri: u32, u: f32, v: f32) -> Vec2 {
        let t = &self.uv_lm[tri as usize];
        t[0] * (1.0 - u - v) + t[1] * u + t[2] * v
    }
}
