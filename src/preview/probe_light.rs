//! What the preview draws from the bake's light probes (`probes.json` and
//! `probes.bin` beside the `.glb`, read by [`Probes::read`]): the light of
//! dynamic nodes, and a sphere per probe for the probes view.
//!
//! - **Dynamic nodes** (glTF `extras.radbake.dynamic`: not baked, no
//!   lightmap) are shaded base colour × E/π(p, n) + emissive, where E/π is
//!   [`Probes::irradiance_over_pi`]: the L2 SH irradiance of Ramamoorthi &
//!   Hanrahan (2001, eq. 7–8) interpolated trilinearly between the eight
//!   probes around p, clamped to the outer probes as Bevy's irradiance
//!   volumes sample. It is evaluated **per vertex** on the CPU (clamped at
//!   0) and interpolated linearly across each triangle by the rasterizer,
//!   so light that changes faster than the mesh's vertices are spaced is
//!   smoothed over (an engine evaluates it per pixel). A vertex outside
//!   every grid takes the light at the nearest point of the nearest grid's
//!   box (Bevy would give it none; the preview shows the outer probes).
//! - **Probe spheres**: a UV sphere of [`SEGMENTS`] × [`RINGS`] around each
//!   probe, radius [`RADIUS_PER_SPACING`] × the smallest grid spacing,
//!   white, shaded by that probe's own E/π for each vertex normal (so the
//!   sphere shows the light's direction; also per vertex). Probes found
//!   inside solids (`!valid[i]`, their SH filled from neighbours) are red.
//!   The renderer builds them the first time the probes view is shown
//!   (about 7 KB of vertices and indices per probe).

use super::gpu::{Vertex, PROBE_INVALID, PROBE_LIT};
use crate::probes::{sh, Probes};
use glam::Vec3;

/// Sphere segments around the axis.
pub const SEGMENTS: u32 = 12;
/// Sphere rings from pole to pole.
pub const RINGS: u32 = 8;
/// Sphere radius / the smallest grid spacing.
pub const RADIUS_PER_SPACING: f32 = 0.15;

/// The vertex attribute [`Vertex::probe`] of a probe-lit vertex at world
/// point `p_ws` with normal `n_ws`: rgb = E/π from `probes` (clamped at 0;
/// black without probes), w = [`PROBE_LIT`].
pub fn vertex_light(probes: Option<&Probes>, p_ws: Vec3, n_ws: Vec3) -> [f32; 4] {
    let e = probes
        .and_then(|pr| {
            pr.irradiance_over_pi(p_ws, n_ws)
                .or_else(|| pr.irradiance_over_pi(nearest_in_grids(pr, p_ws)?, n_ws))
        })
        .unwrap_or(Vec3::ZERO);
    e.max(Vec3::ZERO).extend(PROBE_LIT).to_array()
}

/// The point nearest `p_ws` inside the nearest grid's box (pulled in by a
/// hair, so that the grid lookup finds it); None without grids.
fn nearest_in_grids(probes: &Probes, p_ws: Vec3) -> Option<Vec3> {
    probes
        .volumes
        .iter()
        .map(|v| {
            let local = v.to_local(p_ws);
            let q = v
                .world_from_box
                .transform_point3(local.clamp(Vec3::splat(-0.4999), Vec3::splat(0.4999)));
            (q.distance_squared(p_ws), q)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, q)| q)
}

/// The probe spheres' sizes: the smallest distance between neighbouring
/// probes over every grid axis holding more than one probe (a grid of one
/// probe counts its largest cell edge).
pub fn smallest_spacing(probes: &Probes) -> f32 {
    probes
        .volumes
        .iter()
        .map(|v| {
            let cell = v.size() / v.resolution.as_vec3();
            let r = v.resolution.to_array();
            let between = (0..3)
                .filter(|&a| r[a] > 1)
                .map(|a| cell[a])
                .fold(f32::INFINITY, f32::min);
            if between.is_finite() {
                between
            } else {
                cell.max_element()
            }
        })
        .fold(f32::INFINITY, f32::min)
}

/// Indexed triangles: a sphere per probe.
#[derive(Clone, Debug, Default)]
pub struct ProbeSpheres {
    /// (2 + `SEGMENTS` × (`RINGS` − 1)) vertices per probe, probe-lit.
    pub vertices: Vec<Vertex>,
    /// Triangle list, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

/// Unit directions of the sphere's vertices: the +Y pole, `RINGS` − 1
/// rings of `SEGMENTS`, the −Y pole.
fn sphere_directions() -> Vec<Vec3> {
    let mut d = vec![Vec3::Y];
    for r in 1..RINGS {
        let theta = std::f32::consts::PI * r as f32 / RINGS as f32;
        for s in 0..SEGMENTS {
            let phi = std::f32::consts::TAU * s as f32 / SEGMENTS as f32;
            d.push(Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ));
        }
    }
    d.push(Vec3::NEG_Y);
    d
}

/// Triangles over [`sphere_directions`], facing outward.
fn sphere_triangles() -> Vec<u32> {
    let ring = |r: u32, s: u32| 1 + (r - 1) * SEGMENTS + s % SEGMENTS;
    let south = 1 + (RINGS - 1) * SEGMENTS;
    let mut t = Vec::new();
    for s in 0..SEGMENTS {
        t.extend([0, ring(1, s + 1), ring(1, s)]);
        t.extend([south, ring(RINGS - 1, s), ring(RINGS - 1, s + 1)]);
        for r in 1..RINGS - 1 {
            let (a, b) = (ring(r, s), ring(r + 1, s));
            let (c, d) = (ring(r + 1, s + 1), ring(r, s + 1));
            t.extend([a, c, b, a, d, c]);
        }
    }
    t
}

/// A sphere around every probe of `probes` (see the module doc).
pub fn spheres(probes: &Probes) -> ProbeSpheres {
    let dirs = sphere_directions();
    let tris = sphere_triangles();
    let radius = RADIUS_PER_SPACING * smallest_spacing(probes);
    let mut out = ProbeSpheres {
        vertices: Vec::with_capacity(probes.len() * dirs.len()),
        indices: Vec::with_capacity(probes.len() * tris.len()),
    };
    for i in 0..probes.len() {
        let centre = probes.position(i);
        let valid = probes.valid.get(i).copied().unwrap_or(true);
        let first = out.vertices.len() as u32;
        out.vertices.extend(dirs.iter().map(|&n| Vertex {
            position: (centre + n * radius).to_array(),
            normal: n.to_array(),
            probe: if valid {
                sh::irradiance_over_pi(&probes.sh[i], n)
                    .max(Vec3::ZERO)
                    .extend(PROBE_LIT)
                    .to_array()
            } else {
                [0.0, 0.0, 0.0, PROBE_INVALID]
            },
            ..Vertex::default()
        }));
        out.indices.extend(tris.iter().map(|&k| first + k));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::probes::Volume;
    use glam::{Mat4, UVec3};

    /// Two probes 1 m apart along x (the box's other edges 3 m and 0.5 m,
    /// one probe each), the second invalid; probe 0 lit from +Y only.
    fn two_probes() -> Probes {
        let mut lit = [Vec3::ZERO; 9];
        sh::add(&mut lit, Vec3::Y, Vec3::new(1.0, 0.5, 0.25), 4.0);
        Probes {
            volumes: vec![Volume {
                name: "scene".into(),
                world_from_box: Mat4::from_scale(Vec3::new(2.0, 3.0, 0.5)),
                resolution: UVec3::new(2, 1, 1),
                first: 0,
            }],
            sh: vec![lit, lit],
            valid: vec![true, false],
            ..Probes::default()
        }
    }

    #[test]
    fn sphere_faces_outward_and_is_closed() {
        let d = sphere_directions();
        let t = sphere_triangles();
        assert_eq!(d.len() as u32, 2 + SEGMENTS * (RINGS - 1));
        assert_eq!(t.len() as u32, 3 * 2 * SEGMENTS * (RINGS - 1));
        let mut edges = std::collections::HashMap::new();
        for tri in t.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| d[tri[k] as usize]);
            assert!((b - a).cross(c - a).dot(a + b + c) > 0.0, "{tri:?}");
            for k in 0..3 {
                *edges.entry((tri[k], tri[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        // Closed and consistently wound: each directed edge once, and its
        // reverse once.
        for (&(a, b), &n) in &edges {
            assert_eq!((n, edges.get(&(b, a))), (1, Some(&1)), "edge {a}-{b}");
        }
    }

    #[test]
    fn spheres_sit_on_probes_shaded_by_their_irradiance() {
        let probes = two_probes();
        assert_eq!(smallest_spacing(&probes), 1.0);
        let s = spheres(&probes);
        let per = (2 + SEGMENTS * (RINGS - 1)) as usize;
        assert_eq!(s.vertices.len(), 2 * per);
        assert!(s.indices.iter().all(|&i| (i as usize) < s.vertices.len()));
        let top = s.vertices[0];
        let want = probes.position(0) + Vec3::Y * RADIUS_PER_SPACING;
        assert!((Vec3::from(top.position) - want).length() < 1e-6);
        let e = sh::irradiance_over_pi(&probes.sh[0], Vec3::Y);
        assert_eq!(top.probe, [e.x, e.y, e.z, PROBE_LIT]);
        assert!(e.x > 0.1);
        // The bottom faces away from the light: clamped at 0, not negative.
        let bottom = s.vertices[per - 1];
        assert!(bottom.probe[..3].iter().all(|&c| c >= 0.0 && c < 0.1 * e.x));
        // The invalid probe is a red marker.
        assert!(s.vertices[per..]
            .iter()
            .all(|v| v.probe[3] == PROBE_INVALID));
    }

    #[test]
    fn vertex_light_interpolates_and_clamps_into_the_grid() {
        let probes = two_probes();
        let inside = vertex_light(Some(&probes), Vec3::ZERO, Vec3::Y);
        let e = sh::irradiance_over_pi(&probes.sh[0], Vec3::Y);
        assert_eq!(inside, [e.x, e.y, e.z, PROBE_LIT]);
        // 10 m above the box: the light at its top face.
        let above = vertex_light(Some(&probes), Vec3::new(0.0, 10.0, 0.0), Vec3::Y);
        assert_eq!(above, inside);
        // No probes: black, still probe-lit (no lightmap).
        assert_eq!(
            vertex_light(None, Vec3::ZERO, Vec3::Y),
            [0.0, 0.0, 0.0, PROBE_LIT]
        );
    }
}
