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
    /// Covered texels.
    pub texels: u64,
    /// Area-weighted mean lightmap value (irradiance / π, linear RGB).
    pub mean: [f32; 3],
    /// Atlas page.
    pub page: u32,
    /// Rectangle in the page, (min.x, min.y, max.x, max.y) in [0, 1] (Bevy's `uv_rect`).
    pub uv_rect: [f32; 4],
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
    /// Non-fatal problems.
    pub warnings: Vec<String>,
}
