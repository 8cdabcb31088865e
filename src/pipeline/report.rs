//! `report.json`: the effective settings, per-stage wall times, counters,
//! an energy balance and, per instance, the area-weighted mean lightmap
//! value (what build pipelines and the tests watch).

use crate::config::BakeConfig;
use serde::Serialize;

/// Wall time of one stage.
#[derive(Clone, Debug, Serialize)]
pub struct StageTime {
    /// Stage name (`import`, `unwrap`, `texels`, ...).
    pub stage: String,
    /// Seconds.
    pub seconds: f64,
}

/// Counters of a bake.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Counts {
    /// Triangles after instancing.
    pub triangles: u64,
    /// Node instances of meshes.
    pub instances: u64,
    /// Distinct meshes.
    pub meshes: u64,
    /// Punctual lights.
    pub lights: u64,
    /// Degenerate triangles dropped on import.
    pub degenerate_triangles: u64,
    /// Point/line primitives skipped on import.
    pub skipped_primitives: u64,
    /// Triangle primitives whose index count does not fit their mode
    /// (trailing indices dropped, with a warning naming each).
    pub malformed_primitives: u64,
    /// Triangles that got no lightmap texel.
    pub unmapped_triangles: u64,
    /// Texels touched by two charts (0 for a valid atlas).
    pub chart_overlaps: u64,
    /// Atlas pages.
    pub pages: u64,
    /// Page width × height.
    pub page_size: [u32; 2],
    /// Charts in the atlas.
    pub charts: u64,
    /// Fraction of the atlas covered by charts.
    pub utilization: f32,
    /// Texel density used (texels per metre).
    pub texels_per_meter: f32,
    /// Covered texels.
    pub texels: u64,
    /// Texels inside or under geometry, filled from valid neighbours.
    pub invalid_texels: u64,
    /// Texels crossed by a wall or solid: their sample points are folded
    /// into the exposed part (burial planes, see `burial_planes`).
    pub clipped_texels: u64,
    /// Texels whose centre lay inside a solid and was moved out of it.
    pub moved_texels: u64,
    /// Seam sample pairs (points on UV seams of continuous surfaces).
    pub seam_samples: u64,
    /// Mean |difference| (RGB sum) of bilinear lightmap samples across seams, before and after stitching.
    pub seam_mismatch: [f64; 2],
    /// Patches.
    pub patches: u64,
    /// Non-zeros of F.
    pub nonzeros: u64,
    /// Rays cast (all stages).
    pub rays: u64,
    /// Rays cast for form factors (by the solve, for progressive refinement).
    pub rays_form_factors: u64,
    /// Rays cast for direct light (shadow and hemisphere rays).
    pub rays_direct: u64,
    /// Rays cast by the validity estimate before the final gather.
    pub rays_validity: u64,
    /// Rays cast by the burial stage (along texels and, where a centre
    /// may be inside a solid, over its hemisphere).
    pub rays_burial: u64,
    /// Rays cast by the final gather.
    pub rays_gather: u64,
    /// Light probes baked (0 with `probes = false`).
    pub probes: u64,
    /// Probes found inside solids (filled from their valid neighbours).
    pub invalid_probes: u64,
    /// Rays cast by the probes (sphere rays, emitter samples, shadow rays).
    pub rays_probes: u64,
    /// Shadow rays cast by the shadowmask stage.
    pub rays_shadowmask: u64,
    /// Form-factor rays that left the scene.
    pub rays_escaped: u64,
    /// Form-factor rays that hit the back of a one-sided surface.
    pub rays_back_faces: u64,
    /// Form-factor rays that hit a surface without a texel there.
    pub rays_unmapped: u64,
    /// Solver iterations.
    pub iterations: u64,
    /// Progressive refinement shots.
    pub shots: u64,
    /// Solver's final relative residual.
    pub residual: f32,
}

/// Power balance (W, per RGB channel).
///
/// Light arriving directly (`direct_received`, from direct sampling) is either
/// absorbed or reflected, and reflected light is absorbed somewhere or
/// escapes: `direct_received = absorbed + reflected_escaped` up to the
/// sampling error of F. Independently, `emitted_landing` (the emitters' own
/// form-factor rows) and `direct_received` estimate the same power when only
/// emissive surfaces light the scene.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Energy {
    /// π Σ Aᵢ Eᵢ: power emitted by emissive surfaces.
    pub emitted: [f64; 3],
    /// π Σ Aᵢ Eᵢ Σⱼ Fᵢⱼ: the part of it that lands on a surface (shooting estimate).
    pub emitted_landing: [f64; 3],
    /// π Σ Aᵢ Dᵢ: power arriving directly from every source (gathering estimate).
    pub direct_received: [f64; 3],
    /// π Σ Aᵢ (1 − ρᵢ) Hᵢ.
    pub absorbed: [f64; 3],
    /// π Σ Aᵢ Lᵢ (1 − Σⱼ Fᵢⱼ), Lᵢ = ρᵢ Hᵢ: reflected light that leaves the scene or hits back faces.
    pub reflected_escaped: [f64; 3],
    /// (direct_received − absorbed − reflected_escaped) / direct_received.
    pub relative_imbalance: [f64; 3],
}

/// One instance's result.
#[derive(Clone, Debug, Serialize)]
pub struct InstanceReport {
    /// Node name.
    pub node: String,
    /// Mesh name.
    pub mesh: String,
    /// Surface area (m²) covered by texels.
    pub area: f64,
    /// Area of the valid texels (m²): the rest lies inside or under
    /// geometry.
    pub valid_area: f64,
    /// Covered texels.
    pub texels: u64,
    /// Area-weighted mean irradiance / π (linear RGB) that the surface
    /// receives: every texel as light transport computed it, buried texels
    /// at what they receive (before they are filled from their neighbours).
    /// The physical figure, what an irradiance meter reads.
    pub mean: [f32; 3],
    /// Area-weighted mean of the lightmap as written (invalid texels filled
    /// from their neighbours, seams stitched): what a renderer shows.
    pub lightmap_mean: [f32; 3],
    /// The node's `texel_scale` (its density over the bake's).
    pub texel_scale: f32,
    /// The node's `cast_shadows` (false: left out of the ray caster).
    pub cast_shadows: bool,
    /// The node's `lightmap` (false: no lightmap for engines; its texels,
    /// at a quarter of the density, carry its bounce only).
    pub lightmap: bool,
    /// Atlas page.
    pub page: u32,
    /// Rectangle in the page, (min.x, min.y, max.x, max.y) in [0, 1] (Bevy's `uv_rect`).
    pub uv_rect: [f32; 4],
}

/// One punctual light and the mode it was baked in.
#[derive(Clone, Debug, Serialize)]
pub struct LightReport {
    /// The light's name (its node's where it has none).
    pub name: String,
    /// Its node's name.
    pub node: String,
    /// `directional`, `point` or `spot`.
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// `baked`, `indirect`, `shadowmask` or `realtime`
    /// ([`crate::scene::LightMode`]): the mode it was baked in (`indirect`
    /// for a shadowmask light that got no channel).
    pub mode: &'static str,
    /// A shadowmask light's channel in the shadowmask pages (`r`, `g`, `b`,
    /// `a`); absent for the other modes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shadowmask_channel: Option<&'static str>,
    /// `shadowmask` for a shadowmask light that got no channel (it
    /// overlaps four that hold them) and was baked as `indirect`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub requested: Option<&'static str>,
}

impl LightReport {
    /// The report line of `light`.
    pub fn of(light: &crate::scene::Light) -> LightReport {
        use crate::scene::LightKind;
        LightReport {
            name: light.name.clone(),
            node: light.node.clone(),
            kind: match light.kind {
                LightKind::Directional => "directional",
                LightKind::Point => "point",
                LightKind::Spot { .. } => "spot",
            },
            mode: light.mode.name(),
            shadowmask_channel: None,
            requested: None,
        }
    }

    /// The report lines of a bake's lights, with the shadowmask channels
    /// that `channel` (per light, see [`crate::maps::shadowmask::Shadowmask`])
    /// assigned.
    pub fn all(lights: &[crate::scene::Light], channel: Option<&[Option<u8>]>) -> Vec<LightReport> {
        use crate::scene::LightMode;
        lights
            .iter()
            .enumerate()
            .map(|(l, light)| {
                let mut r = LightReport::of(light);
                if light.mode == LightMode::Shadowmask {
                    let c = channel.and_then(|c| c[l]);
                    r.mode = crate::maps::shadowmask::baked_mode(light, c).name();
                    r.shadowmask_channel =
                        c.map(|c| crate::maps::shadowmask::CHANNEL_NAMES[c as usize]);
                    r.requested = c.is_none().then_some(LightMode::Shadowmask.name());
                }
                r
            })
            .collect()
    }
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// radbake version.
    pub radbake_version: String,
    /// The scene file.
    pub scene: String,
    /// Effective settings.
    pub settings: BakeConfig,
    /// Per-stage wall time.
    pub stages: Vec<StageTime>,
    /// Counters.
    pub counts: Counts,
    /// Power balance.
    pub energy: Energy,
    /// Per instance.
    pub instances: Vec<InstanceReport>,
    /// Per punctual light, with its bake mode.
    pub lights: Vec<LightReport>,
    /// Non-fatal problems.
    pub warnings: Vec<String>,
}

/// Peak resident memory of this process in bytes (`VmHWM` in
/// `/proc/self/status`); `None` where there is no such file (not Linux).
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// `n` with an SI prefix: 1234567 → "1.23 M".
fn si(n: f64) -> String {
    match n {
        n if n >= 1e9 => format!("{:.2} G", n / 1e9),
        n if n >= 1e6 => format!("{:.2} M", n / 1e6),
        n if n >= 1e3 => format!("{:.1} k", n / 1e3),
        n => format!("{n:.0}"),
    }
}

impl Report {
    /// Rays cast in `stage` (form factors, direct light, final gather; the
    /// form factors of progressive refinement are cast by the solve).
    pub fn stage_rays(&self, stage: &str) -> u64 {
        let c = &self.counts;
        let progressive = self.settings.solver == crate::config::Solver::Progressive;
        match stage {
            "form_factors" if !progressive => c.rays_form_factors,
            "solve" if progressive => c.rays_form_factors,
            "direct" => c.rays_direct,
            "validity" => c.rays_validity,
            "burial" => c.rays_burial,
            "final_gather" => c.rays_gather,
            "probes" => c.rays_probes,
            "shadowmask" => c.rays_shadowmask,
            _ => 0,
        }
    }

    /// A compact table for people (`radbake bake --stats`): per-stage wall
    /// time, rays and rays/s, the total, then the counters and `peak_rss`
    /// (bytes, when known).
    pub fn stats_table(&self, peak_rss: Option<u64>) -> String {
        use std::fmt::Write as _;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{:<13} {:>9} {:>7} {:>10} {:>10}",
            "stage", "time (s)", "share", "rays", "rays/s"
        );
        let total: f64 = self.stages.iter().map(|s| s.seconds).sum();
        let mut row = |name: &str, seconds: f64, rays: u64| {
            let share = if total > 0.0 {
                100.0 * seconds / total
            } else {
                0.0
            };
            let (r, rate) = if rays > 0 {
                (si(rays as f64), si(rays as f64 / seconds.max(1e-9)))
            } else {
                (String::new(), String::new())
            };
            let line = format!("{name:<13} {seconds:>9.3} {share:>6.1}% {r:>10} {rate:>10}");
            let _ = writeln!(out, "{}", line.trim_end());
        };
        for s in &self.stages {
            row(&s.stage, s.seconds, self.stage_rays(&s.stage));
        }
        row("total", total, self.counts.rays);
        let c = &self.counts;
        let _ = write!(
            out,
            "triangles {} ({} instances) · texels {} ({} invalid) · patches {} · non-zeros of F {} · ",
            c.triangles, c.instances, c.texels, c.invalid_texels, c.patches, si(c.nonzeros as f64)
        );
        if c.shots > 0 {
            let _ = write!(out, "shots {} · ", c.shots);
        } else {
            let _ = write!(out, "iterations {} · ", c.iterations);
        }
        let _ = write!(out, "residual {:.1e}", c.residual);
        match peak_rss {
            Some(b) => {
                let _ = writeln!(out, " · peak memory {:.0} MB", b as f64 / 1e6);
            }
            None => out.push('\n'),
        }
        out
    }
}
