//! Bake settings: one serde struct, read from `bake.toml` or built from CLI
//! flags, validated before any work starts.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Where the lightmap UVs come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum UvSource {
    /// Unwrap every mesh with `uvunwrap`.
    Unwrap,
    /// Repack the input's `TEXCOORD_1` islands (scaled to the texel density).
    Existing,
}

/// How the unwrapper packs charts into the atlas.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Packing {
    /// Rows of charts pushed together by their per-row and per-column
    /// extents (`uvunwrap`'s `Packing::Fast`): on the real scenes as dense
    /// as `shape` and up to 25 × faster (docs/performance.md).
    Fast,
    /// Rasterised chart shapes nested into each other's concavities
    /// (`uvunwrap`'s `Packing::Shape`): can be denser, can be far slower
    /// with many charts (24 s for a 58 k-triangle level).
    Shape,
}

/// How form factors are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum FormFactorMethod {
    /// Cosine-distributed rays from each patch (Wallace et al. 1989 style Monte Carlo).
    Raycast,
    /// Hemicube rasterisation at each patch centroid (Cohen & Greenberg 1985).
    Hemicube,
}

/// How the radiosity system is solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Solver {
    /// Jacobi iteration on the stored sparse F.
    Jacobi,
    /// Gauss–Seidel iteration on the stored sparse F.
    #[serde(rename = "gauss-seidel")]
    #[cfg_attr(feature = "cli", value(name = "gauss-seidel"))]
    GaussSeidel,
    /// Progressive refinement: shooting, rows computed on demand, O(n) memory.
    Progressive,
    /// Dense LU of (I − ρF): exact for the given F, O(n³); small scenes only.
    Direct,
}

/// How emissive surfaces light the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum EmitterSampling {
    /// `direct` for emissive materials covering at most 2 % of the scene's
    /// surface (lamps), `radiosity` for larger ones (glowing walls).
    Auto,
    /// Sampled per texel like lights (soft shadows at texel resolution; MIS noise).
    Direct,
    /// Emission enters the radiosity solve (smooth, at patch resolution).
    Radiosity,
}

/// Directional lightmaps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum DirectionalMode {
    /// None.
    None,
    /// L1 spherical harmonics: four RGB pages a, b_x, b_y, b_z.
    Sh,
}

/// Light layers ([`crate::scene::layers`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum LayerMode {
    /// One lightmap per layer where the scene names a layer (on a light's
    /// node or a material) or `sky_layer` is set; else as `off`.
    #[default]
    Auto,
    /// One lightmap of every light, whatever layers the scene names.
    Off,
}

impl LayerMode {
    fn is_auto(&self) -> bool {
        *self == LayerMode::Auto
    }
}

/// The layer of every light that names none.
pub const STATIC_LAYER: &str = "static";

/// The default [`BakeConfig::live_grid`]: 12 × 12 = 144 directions.
pub const DEFAULT_LIVE_GRID: u32 = 12;

fn default_live_grid() -> u32 {
    DEFAULT_LIVE_GRID
}

fn is_default_live_grid(n: &u32) -> bool {
    *n == DEFAULT_LIVE_GRID
}

/// The default [`BakeConfig::live_probe_rays`].
pub const DEFAULT_LIVE_PROBE_RAYS: u32 = 64;

fn default_live_probe_rays() -> u32 {
    DEFAULT_LIVE_PROBE_RAYS
}

fn is_default_live_probe_rays(n: &u32) -> bool {
    *n == DEFAULT_LIVE_PROBE_RAYS
}

/// A day's sun path for the live lights ([`BakeConfig::sun_path`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunPathSetting {
    /// Degrees north (−90 to 90).
    pub latitude: f32,
    /// Day of the year (1–366).
    pub day: f32,
    /// Directions along the path.
    #[serde(default = "default_path_samples")]
    pub samples: u32,
}

/// Samples of a day's sun path where none is given.
pub const DEFAULT_SUN_PATH_SAMPLES: u32 = 256;

fn default_path_samples() -> u32 {
    DEFAULT_SUN_PATH_SAMPLES
}

/// The light layer of the live lights' bounced light ([`LightMode::Live`]).
pub const LIVE_LAYER: &str = "live";

/// A light layer's name is a plain identifier: ASCII letters, digits and
/// `_`, 1 to 32 of them, not starting with a digit (it names files:
/// `lightmap_<page>_<layer>.exr`).
pub fn valid_layer_name(name: &str) -> bool {
    let mut chars = name.chars();
    (1..=32).contains(&name.len())
        && chars
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The HDR lightmap pages written as KTX2 (what Bevy loads).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Ktx2Mode {
    /// `lightmap_<page>.ktx2` in `E5B9G9R9_UFLOAT_PACK32`, Zstandard
    /// supercompressed.
    Rgb9e5,
    /// `lightmap_<page>.ktx2` in `BC6H_UFLOAT_BLOCK` (a quarter of RGB9E5's
    /// size on the GPU), Zstandard supercompressed; the atlas then aligns
    /// charts to 4 × 4 blocks.
    Bc6h,
    /// No KTX2 pages.
    Off,
}

impl Ktx2Mode {
    /// The format's name in `manifest.json` (`ktx2_format`); None for `off`.
    pub fn name(self) -> Option<&'static str> {
        match self {
            Ktx2Mode::Rgb9e5 => Some("rgb9e5"),
            Ktx2Mode::Bc6h => Some("bc6h"),
            Ktx2Mode::Off => None,
        }
    }
}

/// The texel format of the signed distance field's KTX2 file
/// ([`crate::output::sdf`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase", try_from = "String")]
pub enum SdfFormat {
    /// `R16_SFLOAT`: half floats, within 2⁻¹¹ of each distance (a
    /// millimetre at 2 m, 5 cm at 100 m), half the size.
    R16f,
    /// `R32_SFLOAT`: the distances as baked.
    #[default]
    R32f,
}

impl SdfFormat {
    /// The Vulkan format's name, as `manifest.json`'s `sdf.format` gives it.
    pub fn vk_name(self) -> &'static str {
        match self {
            SdfFormat::R16f => "R16_SFLOAT",
            SdfFormat::R32f => "R32_SFLOAT",
        }
    }
}

impl TryFrom<String> for SdfFormat {
    type Error = String;

    /// `r16f` or `r32f`; anything else is an error naming the key.
    fn try_from(s: String) -> std::result::Result<Self, String> {
        match s.as_str() {
            "r16f" => Ok(SdfFormat::R16f),
            "r32f" => Ok(SdfFormat::R32f),
            _ => Err(format!(
                "sdf_format = \"{s}\": the distance field's format is \"r16f\" or \"r32f\""
            )),
        }
    }
}

/// What the signed distance field's grid covers ([`crate::sdf::bounds`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(try_from = "String")]
pub enum SdfBounds {
    /// The scene's bounds: every triangle.
    #[default]
    #[serde(rename = "scene")]
    Scene,
    /// The union of the probe volumes' boxes (nodes with
    /// `extras.radbake.probe_volume`), where dynamic objects go: the same
    /// voxels over less space. Distances still measure to every triangle.
    #[serde(rename = "probe-volumes")]
    #[cfg_attr(feature = "cli", value(name = "probe-volumes"))]
    ProbeVolumes,
}

impl SdfBounds {
    /// The value's name (`bake.toml`, the command line, `manifest.json`).
    pub fn name(self) -> &'static str {
        match self {
            SdfBounds::Scene => "scene",
            SdfBounds::ProbeVolumes => "probe-volumes",
        }
    }
}

impl TryFrom<String> for SdfBounds {
    type Error = String;

    /// `scene` or `probe-volumes`; anything else is an error naming the key.
    fn try_from(s: String) -> std::result::Result<Self, String> {
        match s.as_str() {
            "scene" => Ok(SdfBounds::Scene),
            "probe-volumes" => Ok(SdfBounds::ProbeVolumes),
            _ => Err(format!(
                "sdf_bounds = \"{s}\": the distance field covers \"scene\" or \"probe-volumes\""
            )),
        }
    }
}

/// How texel values are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Radiosity (form factors, solve, final gather): the baker.
    Radiosity,
    /// Path tracing from every texel: the reference (slow, independent of patches).
    Pathtrace,
    /// Photon mapping (Jensen), with the final gather when `final_gather` > 0.
    Photon,
}

/// Where the rays of the form factors are cast.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Device {
    /// CPU threads (radbake's SIMD BVH4).
    Cpu,
    /// A wgpu compute shader (falls back to the CPU, with a warning, where no adapter exists).
    Gpu,
}

/// Named starting points for the settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// [`BakeConfig::preview`].
    Preview,
    /// [`BakeConfig::medium`] (the default).
    Medium,
    /// [`BakeConfig::production`].
    Production,
}

/// All bake settings. Every field has a default; `bake.toml` may set any
/// subset (unknown keys are rejected).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BakeConfig {
    /// Lightmap texels per metre (> 0). Higher is sharper and slower (cost ∝ density²).
    pub texels_per_meter: f32,
    /// Empty texels around each chart (≥ 4, so bilinear filtering and dilation never bleed).
    pub padding: u32,
    /// Patch size: patches are k×k texel blocks inside one chart (1..=64). Smaller is more accurate, cost ∝ 1/k⁴.
    pub patch_texels: u32,
    /// Form-factor rays cast from each patch (≥ 16). Noise in F falls as 1/√rays.
    pub rays_per_patch: u32,
    /// Jacobi stops when the relative change of radiance falls below this (> 0).
    pub tolerance: f32,
    /// Jacobi stops after this many iterations at most (≥ 1).
    pub max_iterations: u32,
    /// Lightmap UV source.
    pub uv: UvSource,
    /// Chart packing.
    pub packing: Packing,
    /// Form-factor method.
    pub form_factors: FormFactorMethod,
    /// Hemicube top-face resolution in pixels (8..=2048, even).
    pub hemicube_resolution: u32,
    /// Solver.
    pub solver: Solver,
    /// Largest patch count the `direct` solver accepts (its cost is O(n³), memory 8n² bytes).
    pub direct_max_patches: u32,
    /// Seed of every random sequence (bakes are deterministic for a seed).
    pub seed: u64,
    /// Texel budget: where the surface would need more lightmap texels than
    /// this at `texels_per_meter`, the density is lowered to fit (with a
    /// warning). This is what makes the presets level-scale as well as
    /// room-scale: `texels_per_meter` is the density of small scenes, the
    /// budget (preview 256 K, medium 1 M, production 4 M: a 512², 1024² or
    /// 2048² lightmap's worth) that of large ones.
    pub max_texels: u64,
    /// Direct-light samples per texel (≥ 1): this many emitter samples and this many hemisphere rays.
    pub direct_samples: u32,
    /// Uniform sky radiance (linear RGB, ≥ 0) seen by rays that leave the scene.
    pub sky: [f32; 3],
    /// An equirectangular HDRI (`.exr` or `.hdr`, linear RGB) seen by rays
    /// that leave the scene instead of `sky` (see [`crate::light::sky`]); None:
    /// the uniform `sky`. A config file's relative path is relative to
    /// the file.
    pub sky_map: Option<std::path::PathBuf>,
    /// Rotation of `sky_map` about +Y in degrees (counter-clockwise seen
    /// from above).
    pub sky_rotation: f32,
    /// Scale of `sky_map`'s radiance (≥ 0).
    pub sky_intensity: f32,
    /// Light samples of `sky_map` per texel and per probe (0–4096),
    /// combined with the cosine (or sphere) rays by MIS: more is less
    /// noise where the map has a bright spot, and a shadow ray each.
    pub sky_samples: u32,
    /// How emissive surfaces are treated.
    pub emitters: EmitterSampling,
    /// Final-gather rays per texel (0: off, texels interpolate the patch solution).
    pub final_gather: u32,
    /// Adaptive final gather: a texel stops at 32, 64, … rays once the
    /// estimated standard error of its total light is at most this
    /// fraction of it (0: every texel casts `final_gather` rays). Off
    /// with `directional = "sh"` or AO, which need every ray.
    pub gather_threshold: f32,
    /// Light samples towards bright patches in the final gather, combined
    /// with its cosine rays by MIS ([`crate::radiosity::patch_lights`]); needs a stored
    /// form-factor matrix (not `solver = "progressive"`).
    pub gather_nee: bool,
    /// The final gather's near field, in texels of the hit instance (the
    /// density used, as `report.json`'s `texels_per_meter`, × its texel scale):
    /// a ray that lands closer reads the local lights' direct light
    /// (emitters, point and spot lights) at its hit point, not the hit
    /// texel's mean ([`crate::radiosity::gather::NearField`]); 0: off.
    pub gather_near_field: f32,
    /// Make both sides of UV seams on continuous surfaces agree.
    pub stitch_seams: bool,
    /// Fold every texel's sample points out of walls and solids that cross
    /// it ([`crate::surface::burial`]); off, rays may start inside them.
    pub burial_planes: bool,
    /// A texel is invalid (inside a solid, filled from its neighbours)
    /// when more than this fraction of its rays meet back faces (0 < x ≤ 1;
    /// Unity's default is 0.1).
    pub backface_tolerance: f32,
    /// Edge-aware à-trous filtering of the gathered indirect light.
    pub denoise: bool,
    /// HDR lightmap pages as KTX2 (`lightmap_<page>.ktx2`).
    pub ktx2: Ktx2Mode,
    /// Light layers: `auto` bakes one lightmap (and probe set) per layer
    /// where the scene names any; `off` bakes one of every light. Left out
    /// of `report.json`'s settings at `auto`.
    #[serde(default, skip_serializing_if = "LayerMode::is_auto")]
    pub layers: LayerMode,
    /// The sky's light layer (a plain identifier; `None`:
    /// [`STATIC_LAYER`], and left out of `report.json`'s settings).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sky_layer: Option<String>,
    /// A live bake's sun directions: an n × n grid over the upper
    /// hemisphere (2–64; [`radbake_live::directions`]). Left out of
    /// `report.json`'s settings at the default.
    #[serde(
        default = "default_live_grid",
        skip_serializing_if = "is_default_live_grid"
    )]
    pub live_grid: u32,
    /// A live bake's rays per probe for the probes' view of the patches
    /// (`live.bin`; [`radbake_live::probes`]): 0 keeps the live layer's
    /// probes as baked, else 1–4096. Left out of `report.json`'s settings
    /// at the default.
    #[serde(
        default = "default_live_probe_rays",
        skip_serializing_if = "is_default_live_probe_rays"
    )]
    pub live_probe_rays: u32,
    /// A sun path for the live lights whose node gives none
    /// (`extras.radbake.sun_path`): their tables are made along it, not over
    /// the hemisphere ([`crate::scene::sun_path`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sun_path: Option<SunPathSetting>,
    /// Bake light probes for dynamic objects ([`crate::probes`]).
    pub probes: bool,
    /// Probe spacing in metres (a `probe_volume` node may set its own).
    pub probe_spacing: f32,
    /// Most probes in all: where the grids would hold more, every spacing
    /// grows by one factor until they fit.
    pub probe_budget: u32,
    /// Rays per probe (a spherical Fibonacci set).
    pub probe_rays: u32,
    /// Also bake the signed distance field (`sdf.ktx2`, see [`crate::sdf`])
    /// with this many voxels along the longest side of what it covers
    /// (`sdf_bounds`: the scene, or its probe volumes; 0: none; at most
    /// 2048).
    pub sdf: u32,
    /// The distance field's texel format: `r16f` (half floats) or `r32f`.
    pub sdf_format: SdfFormat,
    /// What the distance field's grid covers: `scene`, or `probe-volumes`
    /// (the union of the probe volumes' boxes; an error where the scene
    /// has none). `sdf` voxels go along the longest side of that box.
    pub sdf_bounds: SdfBounds,
    /// Directional lightmaps (needs the final gather).
    pub directional: DirectionalMode,
    /// Ambient-occlusion distance in metres (0: no AO map; needs the final gather).
    pub ao_distance: f32,
    /// Punctual lights evaluated at s × s points per texel (1: at its centroid; 1..=8).
    pub supersample: u32,
    /// Light-transport method.
    pub method: Method,
    /// Paths per texel for `method = "pathtrace"` (≥ 1).
    pub path_samples: u32,
    /// Photons emitted for `method = "photon"` (≥ 1).
    pub photons: u64,
    /// Nearest photons per density estimate (1..=4096).
    pub photon_neighbours: u32,
    /// Where form-factor rays are cast (`gpu`: wgpu compute; ray-cast form factors only).
    pub device: Device,
    /// Also write `lightmap_<page>_debug.png` (patches and texel validity, for the preview's debug views).
    pub debug_maps: bool,
    /// Each punctual light's bake mode ([`LightMode`]): defaults per light
    /// type and overrides per light.
    pub light_modes: LightModes,
}

/// What a light contributes to the bake (per light: the node's
/// `extras.radbake.mode`, config defaults per type, `--light-mode`), as
/// Unity's Baked / Mixed / Realtime light modes:
///
/// | mode | lightmap | probes | the engine draws |
/// |---|---|---|---|
/// | `baked` | direct + bounced | direct + bounced | nothing (the bake has it all) |
/// | `indirect` | bounced only | bounced only | the direct light, with its real-time shadows |
/// | `shadowmask` | bounced only, plus its occlusion in a shadowmask channel | bounced only | the direct light × the shadowmask |
/// | `realtime` | nothing | nothing | everything (the light is not baked) |
/// | `live` | as `indirect`, its bounced light in the light layer `live`, which `live.bin` re-solves at run time for any direction (directional lights only; see `radbake_live`) | as `indirect` (as baked) | the direct light, with its real-time shadows |
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum LightMode {
    /// Direct and bounced light in the lightmap and the probes.
    #[default]
    Baked,
    /// Only the bounced light; the engine draws the direct light in real time.
    Indirect,
    /// As `indirect`, plus the light's occlusion in a shadowmask channel.
    Shadowmask,
    /// Not baked at all.
    Realtime,
    /// As `indirect`, its bounced light re-solved at run time for any sun
    /// direction (`live.bin`, [`radbake_live`]).
    Live,
}

impl LightMode {
    /// The name used in glTF extras, config and the CLI.
    pub fn name(self) -> &'static str {
        match self {
            LightMode::Baked => "baked",
            LightMode::Indirect => "indirect",
            LightMode::Shadowmask => "shadowmask",
            LightMode::Realtime => "realtime",
            LightMode::Live => "live",
        }
    }

    /// Every mode, in the order of the table above.
    pub const ALL: [LightMode; 5] = [
        LightMode::Baked,
        LightMode::Indirect,
        LightMode::Shadowmask,
        LightMode::Realtime,
        LightMode::Live,
    ];

    /// Parses a mode name (one of [`LightMode::ALL`]'s names).
    pub fn parse(name: &str) -> Option<LightMode> {
        LightMode::ALL.into_iter().find(|m| m.name() == name)
    }

    /// True for a light whose direct light the bake leaves to the engine
    /// but whose bounced light it bakes (`indirect`, `shadowmask`, `live`).
    pub fn is_mixed(self) -> bool {
        matches!(
            self,
            LightMode::Indirect | LightMode::Shadowmask | LightMode::Live
        )
    }
}

/// The bake mode of each punctual light ([`LightMode`]). A light's mode is,
/// first found: `lights[name]` (its light's or its node's name; the CLI's
/// `--light-mode NAME=MODE`), its node's `extras.radbake.mode`, the default
/// of its type here, `baked`.
///
/// ```toml
/// [light_modes]
/// directional = "indirect"
/// [light_modes.lights]
/// Lamp = "realtime"
/// ```
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LightModes {
    /// Directional lights whose node sets no mode.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub directional: Option<LightMode>,
    /// Point lights whose node sets no mode.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub point: Option<LightMode>,
    /// Spot lights whose node sets no mode.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spot: Option<LightMode>,
    /// Per light, by its light's or its node's name: overrides the rest.
    pub lights: std::collections::BTreeMap<String, LightMode>,
}

impl Default for BakeConfig {
    fn default() -> Self {
        Self::medium()
    }
}

impl BakeConfig {
    /// Balanced defaults: the Cornell box gets about 64×64 texels per wall.
    pub const fn medium() -> Self {
        BakeConfig {
            texels_per_meter: 116.0,
            padding: 4,
            patch_texels: 4,
            // With the final gather on, F only carries the second and later
            // bounces: 256 rays change the Cornell box's instance means by
            // under 0.06 % and Sponza's texel noise not at all, against
            // 1024, and save a quarter of Sponza's bake (docs/performance.md).
            rays_per_patch: 256,
            tolerance: 1e-4,
            max_iterations: 200,
            uv: UvSource::Unwrap,
            packing: Packing::Fast,
            form_factors: FormFactorMethod::Raycast,
            hemicube_resolution: 128,
            solver: Solver::Jacobi,
            direct_max_patches: 4096,
            seed: 0x5eed,
            max_texels: 1 << 20,
            direct_samples: 64,
            sky: [0.0; 3],
            sky_map: None,
            sky_rotation: 0.0,
            sky_intensity: 1.0,
            sky_samples: 16,
            emitters: EmitterSampling::Auto,
            final_gather: 128,
            gather_threshold: 0.005,
            gather_nee: false,
            gather_near_field: 1.0,
            stitch_seams: true,
            burial_planes: true,
            backface_tolerance: 0.5,
            denoise: true,
            ktx2: Ktx2Mode::Rgb9e5,
            layers: LayerMode::Auto,
            sky_layer: None,
            live_grid: DEFAULT_LIVE_GRID,
            live_probe_rays: DEFAULT_LIVE_PROBE_RAYS,
            sun_path: None,
            probes: true,
            probe_spacing: 1.0,
            probe_budget: 16_384,
            probe_rays: 256,
            sdf: 0,
            sdf_format: SdfFormat::R32f,
            sdf_bounds: SdfBounds::Scene,
            directional: DirectionalMode::None,
            ao_distance: 0.0,
            supersample: 1,
            method: Method::Radiosity,
            path_samples: 1024,
            photons: 1 << 20,
            photon_neighbours: 128,
            debug_maps: false,
            device: Device::Cpu,
            light_modes: LightModes {
                directional: None,
                point: None,
                spot: None,
                lights: std::collections::BTreeMap::new(),
            },
        }
    }

    /// Quick look: a quarter of the light samples and gather rays, coarser texels, loose tolerance.
    pub fn preview() -> Self {
        let m = Self::medium();
        BakeConfig {
            texels_per_meter: 48.0,
            rays_per_patch: 128,
            direct_samples: 16,
            final_gather: 32,
            probe_budget: 2048,
            probe_rays: 128,
            tolerance: 1e-3,
            max_texels: 1 << 18,
            ..m
        }
    }

    /// Final quality: smaller patches, 4× the rays and light samples, tight tolerance.
    pub fn production() -> Self {
        let m = Self::medium();
        BakeConfig {
            patch_texels: 2,
            rays_per_patch: 1024,
            direct_samples: 256,
            final_gather: 512,
            probe_budget: 65_536,
            probe_rays: 1024,
            tolerance: 1e-5,
            max_texels: 1 << 22,
            ..m
        }
    }

    /// The settings of a [`Preset`].
    pub fn preset(p: Preset) -> Self {
        match p {
            Preset::Preview => Self::preview(),
            Preset::Medium => Self::medium(),
            Preset::Production => Self::production(),
        }
    }

    /// `bake.toml` laid over `base`: keys the file sets replace the base's.
    ///
    /// # Errors
    /// [`Error::Config`] naming an unknown key or a bad value.
    pub fn from_toml_over(base: &BakeConfig, text: &str) -> Result<Self> {
        let bad = |message: String| Error::Config {
            key: "bake.toml".into(),
            message,
        };
        let file: toml::Table = toml::from_str(text).map_err(|e| bad(e.message().to_owned()))?;
        let mut merged = toml::Table::try_from(base).map_err(|e| bad(e.to_string()))?;
        for (k, v) in file {
            merged.insert(k, v);
        }
        let cfg: BakeConfig = merged
            .try_into()
            .map_err(|e: toml::de::Error| bad(e.message().to_owned()))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks every value's range.
    ///
    /// # Errors
    /// [`Error::Config`] naming the first key out of range.
    pub fn validate(&self) -> Result<()> {
        let bad = |key: &str, message: &str| {
            Err(Error::Config {
                key: key.into(),
                message: message.into(),
            })
        };
        if !(self.texels_per_meter.is_finite() && self.texels_per_meter > 0.0) {
            return bad("texels_per_meter", "must be a finite number > 0");
        }
        if self.padding < 1 || self.padding > 64 {
            return bad("padding", "must be in 1..=64");
        }
        if self.patch_texels < 1 || self.patch_texels > 64 {
            return bad("patch_texels", "must be in 1..=64");
        }
        if self.rays_per_patch < 16 || self.rays_per_patch > 1 << 20 {
            return bad("rays_per_patch", "must be in 16..=1048576");
        }
        if self.hemicube_resolution < 8 || self.hemicube_resolution > 2048 {
            return bad("hemicube_resolution", "must be in 8..=2048");
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return bad("tolerance", "must be a finite number > 0");
        }
        if self.max_iterations < 1 {
            return bad("max_iterations", "must be ≥ 1");
        }
        if self.direct_samples < 1 || self.direct_samples > 1 << 16 {
            return bad("direct_samples", "must be in 1..=65536");
        }
        if self.supersample < 1 || self.supersample > 8 {
            return bad("supersample", "must be in 1..=8");
        }
        if !(self.probe_spacing.is_finite() && self.probe_spacing > 0.0) {
            return bad("probe_spacing", "must be a positive number of metres");
        }
        if self.probe_budget == 0 || self.probe_budget > 1 << 24 {
            return bad("probe_budget", "must be in 1..=16777216");
        }
        if self.probe_rays == 0 || self.probe_rays > 1 << 16 {
            return bad("probe_rays", "must be in 1..=65536");
        }
        if !(self.gather_threshold >= 0.0 && self.gather_threshold < 1.0) {
            return bad("gather_threshold", "must be in [0, 1)");
        }
        if !(self.gather_near_field >= 0.0 && self.gather_near_field <= 64.0) {
            return bad("gather_near_field", "must be in [0, 64]");
        }
        if !(self.backface_tolerance > 0.0 && self.backface_tolerance <= 1.0) {
            return bad("backface_tolerance", "must be in (0, 1]");
        }
        if !(self.ao_distance.is_finite() && self.ao_distance >= 0.0) {
            return bad("ao_distance", "must be a finite number ≥ 0");
        }
        if self.final_gather == 0
            && (self.ao_distance > 0.0 || self.directional != DirectionalMode::None)
        {
            return bad(
                "final_gather",
                "AO and directional maps come from the final gather: it must be > 0",
            );
        }
        if self.final_gather > 1 << 16 {
            return bad("final_gather", "must be in 0..=65536");
        }
        if self.sky.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return bad("sky", "must be three finite numbers ≥ 0");
        }
        if !self.sky_rotation.is_finite() {
            return bad("sky_rotation", "must be a finite number of degrees");
        }
        if !self.sky_intensity.is_finite() || self.sky_intensity < 0.0 {
            return bad("sky_intensity", "must be a finite number ≥ 0");
        }
        if self.sdf > 2048 {
            return bad("sdf", "must be in 0..=2048 voxels along the longest side");
        }
        if self.sky_samples > 4096 {
            return bad("sky_samples", "must be in 0..=4096");
        }
        if self.sky_map.is_some() && self.sky != [0.0; 3] {
            return bad("sky_map", "replaces the uniform sky: leave `sky` at 0,0,0");
        }
        if self.sky_map.is_some() && self.method == Method::Photon {
            return bad(
                "sky_map",
                "photon mapping emits no photons from a sky map: use method = \"radiosity\" or \"pathtrace\"",
            );
        }
        if self.method != Method::Radiosity
            && (self.ao_distance > 0.0 || self.directional != DirectionalMode::None)
        {
            return bad(
                "method",
                "AO and directional maps come from the radiosity bake's final gather: use method = \"radiosity\"",
            );
        }
        if self.path_samples < 1 {
            return bad("path_samples", "must be ≥ 1");
        }
        if self.photons < 1 || self.photons > 1 << 32 {
            return bad("photons", "must be in 1..=4294967296");
        }
        if self.photon_neighbours < 1 || self.photon_neighbours > 4096 {
            return bad("photon_neighbours", "must be in 1..=4096");
        }
        if self.max_texels < 1024 {
            return bad("max_texels", "must be ≥ 1024");
        }
        if !self.sky_layer.as_deref().is_none_or(valid_layer_name) {
            return bad(
                "sky_layer",
                "must be a plain identifier (letters, digits, _; at most 32, not starting with a digit)",
            );
        }
        if self.live_probe_rays > 4096 {
            return bad("live_probe_rays", "must be in 0..=4096");
        }
        if !(2..=64).contains(&self.live_grid) {
            return bad("live_grid", "must be in 2..=64");
        }
        if let Some(p) = &self.sun_path {
            let ok = (-90.0..=90.0).contains(&p.latitude)
                && (1.0..=366.0).contains(&p.day)
                && (2..=4096).contains(&p.samples);
            if !ok {
                return bad(
                    "sun_path",
                    "latitude in −90..90 degrees, day in 1..366, samples in 2..4096",
                );
            }
        }
        Ok(())
    }

    /// Parses a `bake.toml`.
    ///
    /// # Errors
    /// [`Error::Config`] naming an unknown key or a bad value.
    pub fn from_toml(text: &str) -> Result<Self> {
        Self::from_toml_over(&Self::default(), text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        BakeConfig::default().validate().unwrap();
    }

    #[test]
    fn unknown_key_is_named() {
        let err = BakeConfig::from_toml("texels_per_metre = 3").unwrap_err();
        assert!(err.to_string().contains("texels_per_metre"), "{err}");
    }

    #[test]
    fn file_layers_over_preset() {
        let c =
            BakeConfig::from_toml_over(&BakeConfig::production(), "texels_per_meter = 10").unwrap();
        assert_eq!(c.texels_per_meter, 10.0);
        assert_eq!(c.rays_per_patch, BakeConfig::production().rays_per_patch);
        let all = toml::to_string(&BakeConfig::preview()).unwrap();
        assert_eq!(BakeConfig::from_toml(&all).unwrap(), BakeConfig::preview());
    }

    #[test]
    fn bad_range_is_named() {
        let err = BakeConfig::from_toml("patch_texels = 0").unwrap_err();
        assert!(err.to_string().contains("patch_texels"), "{err}");
        for bad in ["backface_tolerance = 0.0", "backface_tolerance = 1.5"] {
            let err = BakeConfig::from_toml(bad).unwrap_err();
            assert!(err.to_string().contains("backface_tolerance"), "{err}");
        }
        let ok = BakeConfig::from_toml("backface_tolerance = 0.1\nburial_planes = false").unwrap();
        assert!(!ok.burial_planes && ok.backface_tolerance == 0.1);
    }

    #[test]
    fn sdf_format_is_r16f_or_r32f() {
        assert_eq!(BakeConfig::default().sdf_format, SdfFormat::R32f);
        let c = BakeConfig::from_toml("sdf = 64\nsdf_format = \"r16f\"").unwrap();
        assert_eq!(c.sdf_format, SdfFormat::R16f);
        let err = BakeConfig::from_toml("sdf_format = \"r8\"").unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("sdf_format") && text.contains("r16f") && text.contains("r32f"),
            "{text}"
        );
        // Written back as it is read.
        let all = toml::to_string(&c).unwrap();
        assert!(all.contains("sdf_format = \"r16f\""), "{all}");
    }

    #[test]
    fn sdf_bounds_is_scene_or_probe_volumes() {
        assert_eq!(BakeConfig::default().sdf_bounds, SdfBounds::Scene);
        let c = BakeConfig::from_toml("sdf_bounds = \"probe-volumes\"").unwrap();
        assert_eq!(c.sdf_bounds, SdfBounds::ProbeVolumes);
        let all = toml::to_string(&c).unwrap();
        assert!(all.contains("sdf_bounds = \"probe-volumes\""), "{all}");
        assert_eq!(BakeConfig::from_toml(&all).unwrap(), c);
        let err = BakeConfig::from_toml("sdf_bounds = \"volumes\"").unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("sdf_bounds") && text.contains("probe-volumes"),
            "{text}"
        );
    }
}
