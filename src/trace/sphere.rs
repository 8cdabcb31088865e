//! The sphere-traced final pass (`radbake render --integrator
//! sphere-trace`, issue #24): every ray is marched through the level's
//! signed distance field ([`crate::sdf::Sdf::march`], Hart 1996) instead
//! of being cast on the BVH.
//!
//! - **Primary visibility**: the camera ray is marched to the field's
//!   surface; the surface there is the triangle nearest a point a voxel
//!   short of the hit (one closest-point query), which gives the material
//!   and the lightmap coordinates. Its radiance is the final pass's: emission + albedo ×
//!   the lightmap (incident irradiance / π, every bounce), plus the direct
//!   light of the lights the lightmap leaves to the engine (modes other
//!   than `baked`).
//! - **Shadow rays** for those lights are marched too, from a voxel off the
//!   surface: a light is seen where the march meets nothing before it.
//! - A ray that leaves the field sees the sky.

use super::render::{Image, View};
use super::Tracer;
use crate::light::lights::punctual_irradiance;
use crate::scene::LightMode;
use crate::sdf::Sdf;
use glam::Vec3;

/// Stream purpose id of the sphere-traced camera rays.
const PURPOSE: u64 = crate::util::sampling::purpose::SPHERE_TRACE;

/// Radiance along camera ray `origin + t·dir`, by sphere tracing.
pub fn radiance(tracer: &Tracer, sdf: &Sdf, origin: Vec3, dir: Vec3) -> Vec3 {
    let Some(t) = sdf.march(origin, dir, f32::INFINITY) else {
        return tracer.lights.sky.radiance(dir);
    };
    // The surface: the triangle nearest a point a voxel short of the hit
    // (on the ray's side, so of two nearly coplanar surfaces, a lamp under
    // a ceiling, the one the ray meets first).
    let p = origin + dir * (t - sdf.grid.voxel).max(0.0);
    let reach = 4.0 * sdf.grid.voxel;
    let Some((tri, _, q)) = tracer.rays.closest_point(p, reach * reach) else {
        return Vec3::ZERO;
    };
    let g = tracer.geometry;
    let (u, v) = g.barycentrics(tri, q);
    let m = g.material[tri as usize];
    let uv0 = g.uv0_at(tri, u, v);
    let ng = g.ng_ws[tri as usize];
    let front = ng.dot(dir) < 0.0;
    let mut l = Vec3::ZERO;
    if front {
        l += tracer.scene.emission_at(m, uv0);
    }
    let albedo = tracer.scene.albedo_at(m, uv0).0;
    if albedo.max_element() <= 0.0 {
        return l;
    }
    let normal = if front { ng } else { -ng };
    let mut h = tracer.lightmaps.as_ref().map_or(Vec3::ZERO, |lm| {
        lm.at(g.page[tri as usize], g.uv_lm_at(tri, u, v))
    });
    h += mixed_lights(tracer, sdf, q, normal);
    l + albedo * h
}

/// Irradiance / π at `p` (normal `n`) from the lights the lightmap leaves
/// to the engine, each shadowed by a marched ray.
fn mixed_lights(tracer: &Tracer, sdf: &Sdf, p: Vec3, n: Vec3) -> Vec3 {
    let origin = p + n * (1.5 * sdf.grid.voxel);
    let mut h = Vec3::ZERO;
    for light in tracer
        .lights
        .punctual
        .iter()
        .filter(|l| l.mode != LightMode::Baked)
    {
        if let Some((value, to, dist)) = punctual_irradiance(light, p, n) {
            let seen = match sdf.march(origin, to, dist) {
                None => true,
                Some(t) => t >= dist - 2.0 * sdf.grid.voxel,
            };
            if seen {
                h += value;
            }
        }
    }
    h
}

/// Renders `size` pixels at `spp` stratified samples each by sphere
/// tracing `sdf` (see the module doc); `advance` gets the rows done.
pub fn render(
    tracer: &Tracer,
    sdf: &Sdf,
    view: &View,
    size: (u32, u32),
    spp: u32,
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Image {
    super::render::render_pixels(view, size, spp, (seed, PURPOSE), advance, |dir, _| {
        radiance(tracer, sdf, view.eye, dir)
    })
}
