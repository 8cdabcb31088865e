//! The bake's summary: [`Bake`] → [`Report`] (`report.json`): per-instance
//! means, the power balance of the patch solution, and the counters.

use super::Bake;
use crate::pipeline::report::{Counts, Energy, InstanceReport, Report};

impl Bake<'_> {
    /// Per instance: the area-weighted mean of the light that arrives
    /// (`mean`: texel values as light transport left them over each
    /// texel's exposed part, and nothing over buried parts and invalid
    /// texels, see [`crate::surface::burial`]), of the filled and stitched lightmap
    /// (`lightmap_mean`), and the area of valid texels.
    pub fn instance_reports(&self) -> Vec<InstanceReport> {
        let n = self.scene.instances.len();
        let mut acc = vec![InstanceSums::default(); n];
        for t in 0..self.texels.len() {
            let sums = &mut acc[self.texels.instance[t] as usize];
            let a = self.texels.area[t] as f64;
            // What the texel receives: its value over its exposed part,
            // nothing over the part behind its burial planes, nothing if
            // it is invalid (inside a solid).
            let exposed = if self.transport.valid[t] {
                self.burial.exposed(t) as f64
            } else {
                0.0
            };
            let arrived = self.transport.values[t];
            let lightmap = self.maps.lightmaps.texel_values[t];
            sums.area += a;
            sums.texels += 1;
            if self.transport.valid[t] {
                sums.valid_area += a;
            }
            for c in 0..3 {
                sums.arrived[c] += a * exposed * arrived[c] as f64;
                sums.lightmap[c] += a * lightmap[c] as f64;
            }
        }
        self.scene
            .instances
            .iter()
            .zip(&acc)
            .enumerate()
            .map(|(i, (inst, sums))| {
                let r = self.atlas.instances[i];
                let mean = |sum: &[f64; 3]| {
                    std::array::from_fn(|c| {
                        if sums.area > 0.0 {
                            (sum[c] / sums.area) as f32
                        } else {
                            0.0
                        }
                    })
                };
                InstanceReport {
                    node: inst.node.clone(),
                    mesh: self.scene.meshes[inst.mesh as usize].name.clone(),
                    area: sums.area,
                    valid_area: sums.valid_area,
                    texels: sums.texels,
                    mean: mean(&sums.arrived),
                    lightmap_mean: mean(&sums.lightmap),
                    texel_scale: inst.texel_scale,
                    cast_shadows: inst.cast_shadows,
                    lightmap: inst.lightmap,
                    page: r.page,
                    uv_rect: [r.min[0], r.min[1], r.max[0], r.max[1]],
                }
            })
            .collect()
    }

    /// The power balance of the solution (see [`Energy`]).
    pub fn energy(&self) -> Energy {
        let mut e = Energy::default();
        let Some(light) = &self.transport.patch_light else {
            return e;
        };
        let p = &self.patches;
        let s = &light.solution;
        let rows = &light.row_sums;
        let pi = std::f64::consts::PI;
        for (i, row_sum) in rows.iter().enumerate() {
            // What sheds and receives light: the part not inside or under
            // geometry.
            let a = p.exposed_area[i] as f64;
            for c in 0..3 {
                let emitted = pi * a * p.emission[i][c] as f64;
                e.emitted[c] += emitted;
                e.emitted_landing[c] += emitted * *row_sum as f64;
                e.direct_received[c] += pi * a * light.direct[i][c] as f64;
                e.absorbed[c] += pi * a * (1.0 - p.albedo[i][c] as f64) * s.irradiance[i][c] as f64;
                e.reflected_escaped[c] +=
                    pi * a * s.radiance[i][c] as f64 * (1.0 - *row_sum as f64);
            }
        }
        for c in 0..3 {
            e.relative_imbalance[c] = if e.direct_received[c] > 0.0 {
                (e.direct_received[c] - e.absorbed[c] - e.reflected_escaped[c])
                    / e.direct_received[c]
            } else {
                0.0
            };
        }
        e
    }

    /// The report for this bake of `scene_path`.
    pub fn report(&self, scene_path: &str) -> Report {
        let st = &self.scene.stats;
        let patch_light = self.transport.patch_light.as_ref();
        let ff = patch_light.map(|p| p.stats.clone()).unwrap_or_default();
        let solution = patch_light.map(|p| &p.solution);
        let rays = &self.transport.rays;
        let probes = self.probes.as_ref();
        Report {
            radbake_version: env!("CARGO_PKG_VERSION").into(),
            scene: scene_path.into(),
            settings: self.config.clone(),
            stages: self.stages.clone(),
            counts: Counts {
                triangles: self.geometry.len() as u64,
                instances: self.scene.instances.len() as u64,
                meshes: self.scene.meshes.len() as u64,
                lights: self.scene.lights.len() as u64,
                degenerate_triangles: st.degenerate_triangles,
                skipped_primitives: st.skipped_primitives,
                malformed_primitives: st.malformed_primitives,
                unmapped_triangles: self.texels.unmapped_triangles,
                chart_overlaps: self.texels.chart_overlaps,
                pages: self.atlas.page_count as u64,
                page_size: [self.atlas.width, self.atlas.height],
                charts: self.atlas.chart_count as u64,
                utilization: self.atlas.utilization,
                texels_per_meter: self.atlas.texels_per_meter,
                texels: self.texels.len() as u64,
                patches: self.patches.len() as u64,
                nonzeros: patch_light
                    .and_then(|p| p.form_factors.as_ref())
                    .map_or(0, |f| f.nnz() as u64),
                rays: rays.total()
                    + self.burial.stats.rays
                    + probes.map_or(0, |p| p.rays)
                    + self.shadowmask.as_ref().map_or(0, |m| m.rays),
                probes: probes.map_or(0, |p| p.len() as u64),
                invalid_probes: probes.map_or(0, |p| p.invalid() as u64),
                rays_probes: probes.map_or(0, |p| p.rays),
                rays_shadowmask: self.shadowmask.as_ref().map_or(0, |m| m.rays),
                rays_burial: self.burial.stats.rays,
                clipped_texels: self.burial.stats.clipped,
                moved_texels: self.burial.stats.moved,
                rays_form_factors: rays.form_factors,
                rays_direct: rays.direct,
                rays_validity: rays.validity,
                rays_gather: rays.gather,
                invalid_texels: self.maps.invalid_texels,
                seam_samples: self.maps.seam_samples,
                seam_mismatch: self.maps.seam_mismatch,
                rays_escaped: ff.escaped,
                rays_back_faces: ff.back_faces,
                rays_unmapped: ff.unmapped,
                iterations: solution.map_or(0, |s| s.iterations as u64),
                shots: solution.map_or(0, |s| s.shots),
                residual: solution.map_or(0.0, |s| s.residual),
            },
            energy: self.energy(),
            instances: self.instance_reports(),
            lights: crate::pipeline::report::LightReport::all(
                &self.scene.lights,
                self.shadowmask.as_ref().map(|m| m.channel.as_slice()),
            ),
            warnings: self.warnings.clone(),
        }
    }
}

/// One instance's sums over its texels.
#[derive(Clone, Default)]
struct InstanceSums {
    area: f64,
    valid_area: f64,
    texels: u64,
    /// Σ area × the light that arrived.
    arrived: [f64; 3],
    /// Σ area × the lightmap value.
    lightmap: [f64; 3],
}
